//! Link against the system PocketSphinx and SphinxBase (Debian `libpocketsphinx-dev`,
//! `libsphinxbase-dev`, version 0.8+5prealpha). Fails with a hint when they are missing.

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    let found = [
        "/usr/lib",
        "/usr/lib/x86_64-linux-gnu",
        "/usr/lib/aarch64-linux-gnu",
        "/usr/local/lib",
    ]
    .iter()
    .any(|d| std::path::Path::new(d).join("libpocketsphinx.so").exists());
    if !found {
        println!(
            "cargo:warning=libpocketsphinx.so not found: install the Debian packages libpocketsphinx-dev pocketsphinx-en-us (scripts/lib.sh need_voice_debs)"
        );
    }
    println!("cargo:rustc-link-lib=dylib=pocketsphinx");
    println!("cargo:rustc-link-lib=dylib=sphinxbase");
}
