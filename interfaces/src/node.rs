//! The component runtime: what every robocog process does the same way.
//!
//! A component is a type implementing [`Component`] in its library (its flags, its interface,
//! its loop); its `main.rs` is one line, [`main`]`::<TheComponent>()`, which parses the flags
//! (the component's own beside [`NodeArgs`]) and calls [`run`]. The runtime then:
//! - prints the component's interface as JSON and exits for `--describe` (what `robocog check`
//!   reads to match inputs with outputs across a graph);
//! - sets up logging (`RUST_LOG`, default `info`), with the component's name on every line;
//! - joins the bus and declares the component's liveliness token;
//! - gives the bus its clock: the system's, or with `--clock bus` a virtual clock set by the
//!   `clock` topic (a replay's time), which the component's timers and stamps then follow;
//! - publishes the bus counters on `diagnostics` once a second;
//! - turns SIGTERM and Ctrl-C into a [`Shutdown`] the component's code awaits;
//! - exits 0 on a clean return, 1 with the error's whole cause chain otherwise; or
//!   [`EX_CONFIG`] (78) when the component cannot start for a reason a restart cannot fix (an
//!   error of [`Component::prepare`], or a [`ConfigError`] anywhere in the chain), and
//!   [`EX_USAGE`] (64) for flags it cannot parse. The launcher does not restart a component that
//!   exits with either: it stops the graph at once with the component's message.
//! - with `--preflight`, runs [`Component::prepare`] alone and exits: 0 when the component could
//!   start, [`EX_CONFIG`] with the reason when it could not (what `robocog check` runs to find
//!   missing files and devices before a launch).

use crate::args::ConnectArgs;
use crate::bus::{Bus, BusOptions};
use crate::header::{Clock, Header};
use crate::msg::Message;
use crate::msg::diag::{Counter, Diagnostics};
use crate::topic::{Service, Topic};
use serde::{Deserialize, Serialize};
use std::future::Future;
use std::process::ExitCode;
use std::time::Duration;
use tokio::sync::watch;

/// Exit code of a component that cannot start for a reason a restart cannot fix: a missing or
/// malformed file, no such device (sysexits' `EX_CONFIG`).
pub const EX_CONFIG: u8 = 78;
/// Exit code of a component given flags it cannot parse (sysexits' `EX_USAGE`).
pub const EX_USAGE: u8 = 64;

/// An error that a restart cannot fix (a missing file, no such device or port, a malformed
/// configuration): a component whose error chain holds one exits with [`EX_CONFIG`]. Errors of
/// [`Component::prepare`] are configuration errors without it.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct ConfigError(pub String);

/// A [`ConfigError`] as an `anyhow` error.
pub fn config_error(message: impl std::fmt::Display) -> anyhow::Error {
    anyhow::Error::new(ConfigError(message.to_string()))
}

/// Exit code of `--preflight` when the component cannot tell yet: what it needs is made by the
/// running graph (a simulated device another component writes). Sysexits' `EX_TEMPFAIL`.
pub const EX_TEMPFAIL: u8 = 75;

/// A [`Component::prepare`] error meaning "what I need does not exist yet, and another part of
/// the running graph makes it": in a start the component waits for it; under `--preflight`
/// (see [`preflight`]) it returns this instead, and exits with [`EX_TEMPFAIL`].
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct NotYetCheckable(pub String);

static PREFLIGHT: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Whether this process only checks its configuration (`--preflight`): a `prepare` that would
/// wait for something the running graph makes returns [`NotYetCheckable`] instead of waiting.
pub fn preflight() -> bool {
    PREFLIGHT.load(std::sync::atomic::Ordering::Relaxed)
}

/// The error of binding `what` to `addr`: a [`ConfigError`] when no restart can fix it (the
/// address is not one of this machine's, or the port is privileged), a plain error when one may
/// (the port is still held by the previous instance, or by another program for now).
pub fn bind_error(what: &str, addr: impl std::fmt::Display, e: std::io::Error) -> anyhow::Error {
    use std::io::ErrorKind;
    match e.kind() {
        ErrorKind::AddrNotAvailable => config_error(format!(
            "cannot {what} on {addr}: it is not an address of this machine ({e})"
        )),
        ErrorKind::PermissionDenied => config_error(format!(
            "cannot {what} on {addr}: permission denied (a port below 1024 needs privileges) ({e})"
        )),
        _ => anyhow::anyhow!("cannot {what} on {addr}: {e}"),
    }
}

/// Whether `e`'s chain holds a [`ConfigError`].
pub fn is_config_error(e: &anyhow::Error) -> bool {
    e.chain().any(|c| c.downcast_ref::<ConfigError>().is_some())
}

/// Where a component takes its time from (`--clock`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum ClockSource {
    /// The system's clocks.
    #[default]
    System,
    /// The `clock` topic (a replay's time, see [`crate::clock`]): a virtual clock that stands
    /// still until the first `clock` message and moves only with it.
    Bus,
}

/// Flags every component accepts: the connection flags, `--clock`, `--name` and `--describe`.
#[derive(Debug, Clone, clap::Args)]
pub struct NodeArgs {
    #[command(flatten)]
    pub connect: ConnectArgs,
    /// Print this component's topics and services as JSON and exit.
    #[arg(long)]
    pub describe: bool,
    /// Check the configuration as a start would (read the files, load the models, open the
    /// devices), say so, and exit without joining the bus: 0 when the component could start,
    /// 78 (EX_CONFIG) with the reason when it could not.
    #[arg(long, conflicts_with = "describe")]
    pub preflight: bool,
    /// Name of this instance on the bus (default: the component's name). The launcher sets it to
    /// the manifest's component name.
    #[arg(long, env = "ROBOCOG_COMPONENT")]
    pub name: Option<String>,
    /// Where the component's time comes from: `system`, or `bus` to follow the `clock` topic that
    /// `robocog replay` publishes (timers, time-outs and stamps then run on the recording's time,
    /// at whatever rate it is replayed).
    #[arg(long, env = "ROBOCOG_CLOCK", value_enum, default_value_t = ClockSource::System)]
    pub clock: ClockSource,
}

/// One topic or service end of a component.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Port {
    pub name: String,
    pub type_name: String,
}

/// What a component publishes, subscribes, serves and calls.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Interface {
    pub component: String,
    pub publishes: Vec<Port>,
    pub subscribes: Vec<Port>,
    pub serves: Vec<Port>,
    pub calls: Vec<Port>,
    /// Hardware it claims (`udp:65305`, `serial:/dev/ttyUSB0`, `http:127.0.0.1:8080`).
    pub hardware: Vec<String>,
}

impl Interface {
    pub fn new(component: &str) -> Self {
        Self {
            component: component.to_string(),
            ..Self::default()
        }
    }
    pub fn publishes<T: Message>(mut self, t: &Topic<T>) -> Self {
        self.publishes.push(Port {
            name: t.name().into(),
            type_name: T::TYPE_NAME.into(),
        });
        self
    }
    pub fn subscribes<T: Message>(mut self, t: &Topic<T>) -> Self {
        self.subscribes.push(Port {
            name: t.name().into(),
            type_name: T::TYPE_NAME.into(),
        });
        self
    }
    pub fn serves<Q: Message, R: Message>(mut self, s: &Service<Q, R>) -> Self {
        self.serves.push(Port {
            name: s.name().into(),
            type_name: Q::TYPE_NAME.into(),
        });
        self
    }
    pub fn calls<Q: Message, R: Message>(mut self, s: &Service<Q, R>) -> Self {
        self.calls.push(Port {
            name: s.name().into(),
            type_name: Q::TYPE_NAME.into(),
        });
        self
    }
}

/// Resolves when the component is asked to stop (SIGTERM, Ctrl-C, or its own request).
#[derive(Debug, Clone)]
pub struct Shutdown {
    rx: watch::Receiver<bool>,
}

impl Shutdown {
    /// A shutdown signal and the sender that triggers it (tests, embedding).
    pub fn new() -> (watch::Sender<bool>, Shutdown) {
        let (tx, rx) = watch::channel(false);
        (tx, Shutdown { rx })
    }
    /// Wait until asked to stop.
    pub async fn wait(&mut self) {
        while !*self.rx.borrow() {
            if self.rx.changed().await.is_err() {
                return;
            }
        }
    }
    pub fn is_requested(&self) -> bool {
        *self.rx.borrow()
    }
}

/// Set up `tracing` from `RUST_LOG` (else `default_filter`), writing to stderr, coloured only
/// on a terminal (under the launcher, stderr is a pipe and the launcher colours the prefix).
pub fn init_logging_with(default_filter: &str) {
    use std::io::IsTerminal;
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default_filter));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal())
        .with_target(false)
        .try_init();
}

/// Logging for components: `info`, zenoh's own warnings included.
pub fn init_logging() {
    init_logging_with("info,zenoh=warn");
}

/// One robocog component: its flags, what it declares on the bus, and its loop.
///
/// The loop lives in the component's library, so a test can run it on a bus of its own without
/// the binary; `main.rs` is `fn main() -> ExitCode { interfaces::node::main::<C>() }`.
pub trait Component {
    /// The component's name: the binary's, and on the bus unless the launcher's `--name` says
    /// otherwise.
    const NAME: &'static str;
    /// What it does, in a line: the first line of `--help`.
    const ABOUT: &'static str;
    /// More for `--help`, after the flags (examples, where output goes); empty for none.
    const AFTER_HELP: &'static str = "";
    /// Its own flags, parsed beside [`NodeArgs`].
    type Config: clap::Args + Send + 'static;
    /// What [`Component::prepare`] makes of the flags (often the flags themselves).
    type Prepared: Send + 'static;
    /// The topics and services it publishes, subscribes, serves and calls, and the hardware it
    /// claims (what `--describe` prints and `robocog check` matches). Never fails: a
    /// configuration that cannot be used is `prepare`'s or `run`'s error, not `--describe`'s.
    fn interface(config: &Self::Config) -> Interface;
    /// Check the flags and do the slow or failing setup (read files, load models) before the
    /// component joins the bus, so that it is up, for the launcher and its dependents, only
    /// once it can work. An error here is a configuration error: the component exits with
    /// [`EX_CONFIG`] and the message, before joining, and is not restarted. Put here what a
    /// restart cannot fix; what can come and go (a peer, a network) belongs in `run`.
    fn prepare(config: Self::Config) -> anyhow::Result<Self::Prepared>;
    /// Work the flags ask for that needs no bus (print the state machine's diagram, check a
    /// scenario file and list its steps): when this returns `Some`, the component does it after
    /// [`Component::prepare`] and exits (0, or 1 with the error) without joining the bus.
    fn without_bus(_prepared: &Self::Prepared) -> Option<anyhow::Result<()>> {
        None
    }
    /// Run until `shutdown` resolves (then return `Ok`) or an error ends the component.
    fn run(
        bus: Bus,
        prepared: Self::Prepared,
        shutdown: Shutdown,
    ) -> impl Future<Output = anyhow::Result<()>> + Send;
}

/// The command line of a [`Component`]: the shared flags and its own.
#[derive(Debug, clap::Parser)]
struct Cli<A: clap::Args> {
    #[command(flatten)]
    node: NodeArgs,
    #[command(flatten)]
    config: A,
}

/// The whole `main` of a component: parse its flags (`--help` names it and says what it does),
/// then [`run`] it.
pub fn main<C: Component>() -> ExitCode {
    use clap::{CommandFactory, FromArgMatches};
    let mut command = Cli::<C::Config>::command()
        .name(C::NAME)
        .about(C::ABOUT)
        .version(env!("CARGO_PKG_VERSION"));
    if !C::AFTER_HELP.is_empty() {
        command = command.after_help(C::AFTER_HELP);
    }
    let cli = match command
        .try_get_matches()
        .and_then(|m| Cli::<C::Config>::from_arg_matches(&m))
    {
        Ok(cli) => cli,
        Err(e) if e.use_stderr() => {
            let _ = e.print();
            return ExitCode::from(EX_USAGE);
        }
        // --help, --version.
        Err(e) => e.exit(),
    };
    let interface = C::interface(&cli.config);
    if cli.node.describe {
        return run(cli.node, interface, |_, _| async { Ok(()) });
    }
    init_logging();
    let name = cli.node.name.clone().unwrap_or_else(|| C::NAME.to_string());
    PREFLIGHT.store(cli.node.preflight, std::sync::atomic::Ordering::Relaxed);
    let prepared = match C::prepare(cli.config) {
        Ok(p) => p,
        Err(e)
            if cli.node.preflight
                && e.chain()
                    .any(|c| c.downcast_ref::<NotYetCheckable>().is_some()) =>
        {
            eprintln!("{name}: cannot be checked before the graph runs: {e:#}");
            return ExitCode::from(EX_TEMPFAIL);
        }
        // Under --preflight the reason alone, for `robocog check` to quote; at a start, what it
        // means for the launcher too.
        Err(e) if cli.node.preflight => {
            eprintln!("{name}: cannot start: {e:#}");
            return ExitCode::from(EX_CONFIG);
        }
        Err(e) => {
            eprintln!(
                "{name}: cannot start: {e:#} (a configuration error: exit {EX_CONFIG}, a restart would not fix it)"
            );
            return ExitCode::from(EX_CONFIG);
        }
    };
    if cli.node.preflight {
        drop(prepared);
        println!("{name}: ready to start");
        return ExitCode::SUCCESS;
    }
    match C::without_bus(&prepared) {
        None => {}
        Some(Ok(())) => return ExitCode::SUCCESS,
        Some(Err(e)) => {
            eprintln!("{name}: {e:#}");
            return ExitCode::FAILURE;
        }
    }
    run(cli.node, interface, move |bus, shutdown| {
        C::run(bus, prepared, shutdown)
    })
}

/// Run a component: see the module doc. `body` gets the bus and the shutdown signal and returns
/// when the component is done.
pub fn run<F, Fut>(args: NodeArgs, interface: Interface, body: F) -> ExitCode
where
    F: FnOnce(Bus, Shutdown) -> Fut,
    Fut: Future<Output = anyhow::Result<()>>,
{
    let interface = match args.clock {
        ClockSource::System => interface,
        ClockSource::Bus => interface.subscribes(&crate::topics::CLOCK),
    };
    if args.describe {
        match serde_json::to_string_pretty(&interface) {
            Ok(s) => {
                println!("{s}");
                return ExitCode::SUCCESS;
            }
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::FAILURE;
            }
        }
    }
    init_logging();
    let name = args
        .name
        .clone()
        .unwrap_or_else(|| interface.component.clone());
    if args.preflight {
        // Nothing to prepare beyond the flags, which parsed.
        println!("{name}: ready to start");
        return ExitCode::SUCCESS;
    }
    let runtime = match tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .thread_name(format!("{name}-rt"))
        .build()
    {
        Ok(r) => r,
        Err(e) => {
            eprintln!("{name}: cannot start the async runtime: {e}");
            return ExitCode::FAILURE;
        }
    };
    let result = runtime.block_on(async move {
        // Up (for the launcher) once every service it describes is served.
        let options = BusOptions {
            announce: true,
            ready_after_services: interface.serves.iter().map(|p| p.name.clone()).collect(),
            clock: match args.clock {
                ClockSource::System => Clock::system(),
                ClockSource::Bus => Clock::virtual_unset(),
            },
        };
        let bus = Bus::open_with(&args.connect, &name, options).await?;
        tracing::info!(namespace = bus.namespace(), "{name} joined the bus");
        let _clock = match args.clock {
            ClockSource::System => None,
            ClockSource::Bus => {
                tracing::info!(
                    "following the bus clock (topic {})",
                    crate::topics::CLOCK.name()
                );
                Some(bus.follow_clock().await?)
            }
        };
        let (tx, shutdown) = Shutdown::new();
        tokio::spawn(async move {
            wait_for_signal().await;
            let _ = tx.send(true);
        });
        let diag = tokio::spawn(publish_diagnostics(bus.clone()));
        let result = body(bus, shutdown).await;
        diag.abort();
        result
    });
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if is_config_error(&e) => {
            tracing::error!(
                "{e:#} (a configuration error: exit {EX_CONFIG}, a restart would not fix it)"
            );
            ExitCode::from(EX_CONFIG)
        }
        Err(e) => {
            tracing::error!("{e:#}");
            ExitCode::FAILURE
        }
    }
}

async fn wait_for_signal() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{SignalKind, signal};
        match signal(SignalKind::terminate()) {
            Ok(mut term) => {
                tokio::select! {
                    _ = term.recv() => tracing::info!("SIGTERM: stopping"),
                    _ = tokio::signal::ctrl_c() => tracing::info!("interrupted: stopping"),
                }
            }
            Err(_) => {
                let _ = tokio::signal::ctrl_c().await;
            }
        }
    }
    #[cfg(not(unix))]
    {
        let _ = tokio::signal::ctrl_c().await;
    }
}

/// Publish the bus counters on `diagnostics` once a second, for as long as the component runs.
pub async fn publish_diagnostics(bus: Bus) {
    let Ok(publisher) = bus.publisher(&crate::topics::DIAGNOSTICS).await else {
        tracing::warn!("cannot publish diagnostics");
        return;
    };
    let mut tick = bus.clock().interval(Duration::from_secs(1));
    loop {
        tick.tick().await;
        let mut msg = Diagnostics {
            header: Header::default(),
            component: bus.component().to_string(),
            counters: bus
                .counters()
                .snapshot()
                .into_iter()
                .map(|(name, value)| Counter { name, value })
                .collect(),
        };
        if publisher.publish(&mut msg).await.is_err() {
            return;
        }
    }
}
