//! A component for tests of the bus and the launcher: it talks, listens, serves, crashes, hangs
//! or ignores SIGTERM on demand (the fault nodes of the launcher tests).
#![expect(
    clippy::disallowed_methods,
    reason = "the fault node plays its faults (hangs, crashes, slow replies) in real time"
)]

use clap::{Parser, ValueEnum};
use interfaces::msg::std_msgs::Text;
use interfaces::node::{self, Interface, NodeArgs};
use interfaces::{ServiceError, topics};
use std::process::ExitCode;
use std::time::Duration;

#[derive(Debug, Clone, Copy, ValueEnum)]
enum Role {
    /// Publishes "hello N" on `chatter` at --rate.
    Talker,
    /// Prints "received: <text>" for every message on `chatter`.
    Listener,
    /// Serves `echo`: replies with the request's text in upper case, after --delay-ms.
    EchoServer,
    /// Joins the bus and does nothing.
    Idle,
    /// Never joins the bus (a component that never comes up).
    Silent,
}

/// Test fixture component.
#[derive(Debug, Parser)]
struct Args {
    #[command(flatten)]
    node: NodeArgs,
    #[arg(long, value_enum)]
    role: Role,
    #[arg(long, default_value_t = 20.0)]
    rate: f64,
    #[arg(long, default_value_t = 0)]
    delay_ms: u64,
    /// Echo server: wait this long before serving (a slow start).
    #[arg(long, default_value_t = 0)]
    serve_after_ms: u64,
    /// Exit on its own after this many seconds, with --exit-code.
    #[arg(long)]
    exit_after: Option<f64>,
    #[arg(long, default_value_t = 3)]
    exit_code: u8,
    /// Keep running after SIGTERM (only SIGKILL stops it).
    #[arg(long)]
    ignore_sigterm: bool,
    /// A file it cannot start without: missing, it exits with EX_CONFIG (78) as a component's
    /// `prepare` does, `--preflight` included.
    #[arg(long)]
    needs_file: Option<std::path::PathBuf>,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let mut interface = Interface::new("fixture_node");
    interface = match args.role {
        Role::Talker => interface.publishes(&topics::CHATTER),
        Role::Listener => interface.subscribes(&topics::CHATTER),
        Role::EchoServer => interface.serves(&topics::ECHO),
        Role::Idle | Role::Silent => interface,
    };
    if !args.node.describe
        && let Some(f) = &args.needs_file
        && !f.exists()
    {
        eprintln!(
            "fixture_node: cannot start: no such file {} (a configuration error)",
            f.display()
        );
        return ExitCode::from(node::EX_CONFIG);
    }
    if matches!(args.role, Role::Silent) && !args.node.describe && !args.node.preflight {
        std::thread::sleep(Duration::from_secs(3600));
        return ExitCode::SUCCESS;
    }
    let (role, rate, delay, exit_after, exit_code, ignore) = (
        args.role,
        args.rate,
        args.delay_ms,
        args.exit_after,
        args.exit_code,
        args.ignore_sigterm,
    );
    let serve_after = Duration::from_millis(args.serve_after_ms);
    node::run(args.node, interface, move |bus, mut shutdown| async move {
        if let Some(s) = exit_after {
            tokio::spawn(async move {
                tokio::time::sleep(Duration::from_secs_f64(s)).await;
                eprintln!("exiting on purpose with code {exit_code}");
                std::process::exit(exit_code as i32);
            });
        }
        let work = async {
            match role {
                Role::Talker => {
                    let publisher = bus.publisher(&topics::CHATTER).await?;
                    let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / rate));
                    for n in 0u64.. {
                        tick.tick().await;
                        let mut msg = Text {
                            text: format!("hello {n}"),
                            ..Default::default()
                        };
                        publisher.publish(&mut msg).await?;
                    }
                }
                Role::Listener => {
                    let sub = bus.subscriber(&topics::CHATTER).await?;
                    loop {
                        let msg = sub.recv().await?;
                        println!("received: {} (seq {})", msg.text, msg.header.seq);
                    }
                }
                Role::EchoServer => {
                    tokio::time::sleep(serve_after).await;
                    let _serving = bus
                        .serve(&topics::ECHO, move |req: Text| async move {
                            tokio::time::sleep(Duration::from_millis(delay)).await;
                            if req.text.is_empty() {
                                return Err(ServiceError::bad_request("nothing to echo"));
                            }
                            Ok(Text {
                                text: req.text.to_uppercase(),
                                ..Default::default()
                            })
                        })
                        .await?;
                    std::future::pending::<()>().await;
                }
                Role::Idle | Role::Silent => std::future::pending::<()>().await,
            }
            anyhow::Ok(())
        };
        tokio::select! {
            r = work => r,
            _ = async {
                shutdown.wait().await;
                if ignore {
                    eprintln!("ignoring SIGTERM");
                    std::future::pending::<()>().await;
                }
            } => Ok(()),
        }
    })
}
