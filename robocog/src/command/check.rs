//! `robocog check <manifest>`: validate a graph without running it: the manifest, the binaries,
//! the topics and services between them, the hardware claims, and (unless `--no-preflight`)
//! whether each component could start as configured: its files, models and devices, as the
//! component itself checks them at start (`--preflight`).

use crate::manifest::{Manifest, Overrides};
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The launch manifest (TOML).
    pub manifest: PathBuf,
    #[command(flatten)]
    pub overrides: Overrides,
    /// Skip asking each component whether it could start as configured (`--preflight`: its
    /// files, models and devices); check the graph's structure only.
    #[arg(long)]
    pub no_preflight: bool,
    /// For a graph over several machines: the machine this is. Its components are preflighted
    /// and its certificate looked for; the other machines' components are checked there.
    #[arg(long, env = "ROBOCOG_MACHINE")]
    pub machine: Option<String>,
    /// Print the programs the graph starts, one per line (each component's `binary`, enabled
    /// ones only, once each), and check nothing else: what a build for this graph needs
    /// (`scripts/run` builds just these).
    #[arg(long)]
    pub binaries: bool,
}

/// Exit code 0 when the graph is sound, 1 with every problem listed otherwise.
pub fn execute(args: Args) -> i32 {
    let manifest = match Manifest::load(&args.manifest, &args.overrides) {
        Ok(m) => m,
        Err(problems) => {
            eprintln!("{problems}");
            return 1;
        }
    };
    if args.binaries {
        let programs: std::collections::BTreeSet<&str> = manifest
            .components
            .iter()
            .map(|c| c.binary.as_str())
            .collect();
        for p in programs {
            println!("{p}");
        }
        return 0;
    }
    match crate::check::check(&manifest, !args.no_preflight, args.machine.as_deref()) {
        Ok(report) => {
            for w in &report.warnings {
                eprintln!("warning: {w}");
            }
            let topics: std::collections::BTreeSet<&str> = report
                .interfaces
                .values()
                .flat_map(|i| {
                    i.publishes
                        .iter()
                        .chain(&i.subscribes)
                        .map(|p| p.name.as_str())
                })
                .collect();
            println!(
                "{}: graph {:?} is sound: {} components, {} topics",
                args.manifest.display(),
                manifest.name,
                manifest.components.len(),
                topics.len()
            );
            0
        }
        Err(problems) => {
            eprintln!("{problems}");
            1
        }
    }
}
