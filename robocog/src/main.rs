use clap::{Parser, Subcommand};
use robocog::command;
use std::process::ExitCode;

/// robocog: run, check and inspect graphs of robot components on a zenoh bus.
#[derive(Debug, Parser)]
#[command(name = "robocog", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    verb: Verb,
}

#[derive(Debug, Subcommand)]
enum Verb {
    /// Run every component of a launch manifest as a process, with a router on loopback.
    Launch(command::launch::Args),
    /// Run one machine's share of a graph over several machines: its router, and the components
    /// the launcher places on it.
    Agent(command::agent::Args),
    /// Make the certificates of a graph over several machines: a CA and one per machine.
    Certs(command::certs::Args),
    /// Validate a launch manifest: keys, binaries, dependencies, topics, hardware claims.
    Check(command::check::Args),
    /// List, echo, measure, describe or publish topics of a running graph.
    Topic(command::topic::Args),
    /// List, describe or call the services of a running graph.
    Service(command::service::Args),
    /// The ROS 2 definitions of the message types: list, show, or export as a package.
    Interface(command::interface::Args),
    /// List the live components of a running graph.
    Component(command::component::Args),
    /// Record the topics of a running graph into an MCAP file.
    Record(command::record::Args),
    /// Publish an MCAP recording back onto a namespace, at the recorded pace, scaled, or stepwise.
    Replay(command::replay::Args),
    /// Watch a running graph's topics in the rerun viewer (live, or saved to an .rrd file).
    View(command::view::Args),
    /// One machine's zenoh router as a process of its own (started, and restarted when it
    /// dies, by `launch` and `agent`).
    Router(command::router::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    // The tools' own errors say what went wrong; zenoh's connection warnings would repeat it.
    interfaces::node::init_logging_with("info,zenoh=error");
    if let Verb::Check(args) = cli.verb {
        return ExitCode::from(command::check::execute(args) as u8);
    }
    if let Verb::Interface(args) = cli.verb {
        return match command::interface::execute(args) {
            Ok(code) => ExitCode::from(code.clamp(0, 255) as u8),
            Err(e) => {
                eprintln!("error: {e:#}");
                ExitCode::FAILURE
            }
        };
    }
    let runtime = match tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
    {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: cannot start the async runtime: {e}");
            return ExitCode::FAILURE;
        }
    };
    let result = runtime.block_on(async move {
        match cli.verb {
            Verb::Launch(a) => command::launch::execute(a).await,
            Verb::Agent(a) => command::agent::execute(a).await,
            Verb::Certs(a) => command::certs::execute(a),
            Verb::Topic(a) => command::topic::execute(a).await,
            Verb::Service(a) => command::service::execute(a).await,
            Verb::Component(a) => command::component::execute(a).await,
            Verb::Record(a) => command::record::execute(a).await,
            Verb::Replay(a) => command::replay::execute(a).await,
            Verb::View(a) => command::view::execute(a).await,
            Verb::Router(a) => command::router::execute(a).await,
            Verb::Check(_) | Verb::Interface(_) => Ok(0),
        }
    });
    match result {
        Ok(code) => ExitCode::from(code.clamp(0, 255) as u8),
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
