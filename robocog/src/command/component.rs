//! `robocog component list`: which components are alive, since when, on which host.

use interfaces::liveliness::Token;
use std::time::Duration;

use std::io::Write;

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    pub connect: interfaces::ConnectArgs,
    #[command(subcommand)]
    pub verb: Verb,
}

#[derive(Debug, clap::Subcommand)]
pub enum Verb {
    /// Every live component of the namespace.
    List {
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
    },
}

pub async fn execute(args: Args) -> anyhow::Result<i32> {
    let bus = super::cli_bus(&args.connect).await?;
    let Verb::List { json } = args.verb;
    let mut rows: Vec<(String, String, u32, i64)> = bus
        .graph(Duration::from_millis(700))
        .await?
        .into_iter()
        .filter_map(|t| match t {
            Token::Component {
                name,
                host,
                pid,
                since_ms,
            } => Some((name, host, pid, since_ms)),
            _ => None,
        })
        .collect();
    rows.sort();
    let now_ms = interfaces::header::system_now_ns() / 1_000_000;
    if json {
        let v: Vec<_> = rows
            .iter()
            .map(|(n, h, p, s)| serde_json::json!({"name": n, "host": h, "pid": p, "since_ms": s, "uptime_s": (now_ms - s) as f64 / 1000.0}))
            .collect();
        out!("{}", serde_json::to_string_pretty(&v)?);
    } else if rows.is_empty() {
        out!("no components in namespace {:?}", bus.namespace());
    } else {
        let w = rows.iter().map(|r| r.0.len()).max().unwrap_or(4).max(9);
        out!("{:w$}  {:20}  {:>8}  UP", "COMPONENT", "HOST", "PID");
        for (n, h, p, s) in &rows {
            out!(
                "{n:w$}  {h:20}  {p:>8}  {:.1} s",
                (now_ms - s) as f64 / 1000.0
            );
        }
    }
    Ok(0)
}
