//! The fuzz targets' short run in the test suite: every file of each committed corpus, then a few
//! thousand seeded mutations of them (byte flips, interesting lengths such as 2^32-1, insertions,
//! deletions, truncations, splices), under an allocator that refuses any single allocation
//! beyond `MAX_ALLOCATION`. A refused allocation aborts the test (Rust's allocation-failure
//! handler), a panic fails it, and the mutation's seed is printed so the input can be rebuilt.
//! The long, coverage-guided runs are `scripts/fuzz` (libFuzzer).
#![allow(clippy::unwrap_used, clippy::expect_used)]
// a test fails by panicking
// The bounded allocator is the one `unsafe` here: a GlobalAlloc forwarding to the system's.
#![allow(unsafe_code)]

use robocog_fuzz::{MAX_ALLOCATION, TARGETS, accepts, seeds};
use std::alloc::{GlobalAlloc, Layout, System};
use std::path::{Path, PathBuf};

/// The system allocator, refusing any single allocation beyond `MAX_ALLOCATION`.
struct Bounded;

// SAFETY: every call forwards to `System` with the caller's layout and pointer, unchanged; a
// refused allocation returns null, which `GlobalAlloc` allows (the caller then reports the
// failure).
unsafe impl GlobalAlloc for Bounded {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if layout.size() > MAX_ALLOCATION {
            return std::ptr::null_mut();
        }
        // SAFETY: forwarded as it came.
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if layout.size() > MAX_ALLOCATION {
            return std::ptr::null_mut();
        }
        // SAFETY: forwarded as it came.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` came from `System` with this layout.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if new_size > MAX_ALLOCATION {
            return std::ptr::null_mut();
        }
        // SAFETY: `ptr` came from `System` with this layout.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Bounded = Bounded;

/// Mutations per target in the suite (a few seconds in all; the long runs are libFuzzer's).
const MUTATIONS: usize = 10_000;

fn corpus_dir(target: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("corpus")
        .join(target)
}

/// The inputs that once crashed a target (kept apart from the corpus, which `cargo fuzz cmin`
/// rewrites), replayed like the corpus.
fn regressions_dir(target: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("regressions")
        .join(target)
}

fn corpus(target: &str) -> Vec<(String, Vec<u8>)> {
    let dir = corpus_dir(target);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("no corpus for {target} at {}: {e}", dir.display()))
        .chain(
            std::fs::read_dir(regressions_dir(target))
                .into_iter()
                .flatten(),
        )
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    files
        .into_iter()
        .map(|p| {
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            (name, std::fs::read(&p).unwrap())
        })
        .collect()
}

/// xorshift64*: the same mutations on every run, on every machine.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        if n == 0 {
            0
        } else {
            (self.next() % n as u64) as usize
        }
    }
}

/// Lengths and values that break parsers.
const INTERESTING: [u32; 8] = [
    0,
    1,
    0x7f,
    0xff,
    0xffff,
    0x7fff_ffff,
    0x8000_0000,
    0xffff_ffff,
];

fn mutate(rng: &mut Rng, input: &[u8], other: &[u8]) -> Vec<u8> {
    let mut out = input.to_vec();
    for _ in 0..1 + rng.below(4) {
        match rng.below(7) {
            0 if !out.is_empty() => {
                let i = rng.below(out.len());
                out[i] ^= 1 << rng.below(8);
            }
            1 if !out.is_empty() => {
                let i = rng.below(out.len());
                out[i] = rng.next() as u8;
            }
            2 if out.len() >= 4 => {
                let i = rng.below(out.len() - 3);
                let v = INTERESTING[rng.below(INTERESTING.len())];
                out[i..i + 4].copy_from_slice(&v.to_le_bytes());
            }
            3 => {
                let i = rng.below(out.len() + 1);
                let n = 1 + rng.below(16);
                let bytes: Vec<u8> = (0..n).map(|_| rng.next() as u8).collect();
                out.splice(i..i, bytes);
            }
            4 if !out.is_empty() => {
                let i = rng.below(out.len());
                let n = 1 + rng.below(out.len() - i);
                out.drain(i..i + n);
            }
            5 => out.truncate(rng.below(out.len() + 1)),
            _ if !other.is_empty() => {
                let i = rng.below(out.len() + 1);
                let j = rng.below(other.len());
                out.truncate(i);
                out.extend_from_slice(&other[j..]);
            }
            _ => {}
        }
    }
    out
}

fn run(target: &str, body: fn(&[u8])) {
    let inputs = corpus(target);
    assert!(!inputs.is_empty(), "the {target} corpus is empty");
    for (name, data) in &inputs {
        let r = std::panic::catch_unwind(|| body(data));
        assert!(r.is_ok(), "{target}: corpus file {name} panics");
    }
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15 ^ target.len() as u64);
    for m in 0..MUTATIONS {
        let seed = rng.0;
        let a = &inputs[rng.below(inputs.len())].1;
        let b = &inputs[rng.below(inputs.len())].1;
        let input = mutate(&mut rng, a, b);
        let r = std::panic::catch_unwind(|| body(&input));
        assert!(
            r.is_ok(),
            "{target}: mutation {m} (rng state {seed:#x}) panics on {} bytes: {:02x?}",
            input.len(),
            &input[..input.len().min(256)]
        );
    }
}

macro_rules! short_runs {
    ($($name:ident),* $(,)?) => {
        $(
            #[test]
            fn $name() {
                let (target, body) = TARGETS
                    .iter()
                    .find(|(n, _)| *n == stringify!($name))
                    .expect("a target of that name");
                run(target, *body);
            }
        )*
        #[test]
        fn every_target_has_a_short_run() {
            let here = [$(stringify!($name)),*];
            for (name, _) in TARGETS {
                assert!(here.contains(name), "no short run for the {name} target");
            }
        }
    };
}

short_runs!(
    cdr,
    panel_request,
    mcap,
    manifest,
    urdf,
    dynamixel,
    nao_command,
    nao_debug,
    gamecontroller,
);

/// The seeds themselves must be accepted by their parsers (a seed that is refused at once would
/// fuzz nothing but the first check).
#[test]
fn the_seeds_are_real_inputs() {
    for (target, _) in TARGETS {
        let seeds = seeds(target);
        assert!(!seeds.is_empty(), "no seeds for {target}");
        for (name, data) in seeds {
            assert!(
                accepts(target, &data),
                "{target}: the seed {name} is refused"
            );
        }
    }
}

/// Write the seeds into the corpora: `cargo test -p robocog-fuzz -- --ignored write_seeds`.
#[test]
#[ignore = "writes the corpora's seed files; run by hand when the seeds change"]
fn write_seeds() {
    for (target, _) in TARGETS {
        let dir = corpus_dir(target);
        std::fs::create_dir_all(&dir).unwrap();
        for (name, data) in seeds(target) {
            std::fs::write(dir.join(format!("seed-{name}")), data).unwrap();
        }
    }
}
