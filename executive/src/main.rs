//! The `executive` binary: see [`executive::component`].

use clap::Parser;
use executive::component::{self, Config};
use interfaces::node::{self, NodeArgs};
use std::process::ExitCode;

/// The Executive: plays a game's state machine (touch the ball, or the Nao coach game) between
/// the person's commands, the robot's perception and its body. Prints a readable game log;
/// `--print-diagram` draws the machine.
#[derive(Debug, Parser)]
#[command(name = "executive")]
struct Args {
    #[command(flatten)]
    node: NodeArgs,
    #[command(flatten)]
    config: Config,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let config = args.config;
    let settings = match config.load_settings() {
        Ok(s) => s,
        Err(e) => {
            eprintln!("executive: {e:#}");
            return ExitCode::FAILURE;
        }
    };
    if config.print_diagram || config.print_dot {
        return match component::diagram(config.game, &settings, config.print_dot) {
            Ok(d) => {
                print!("{d}");
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("executive: {e:#}");
                ExitCode::FAILURE
            }
        };
    }
    node::run(
        args.node,
        component::interface(config.game),
        move |bus, shutdown| component::run(bus, config, settings, shutdown),
    )
}
