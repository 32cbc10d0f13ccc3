//! The one set of connection flags every robocog binary accepts.
//!
//! Flatten [`ConnectArgs`] into a component's clap parser. The launcher passes the same values
//! through the environment (`ROBOCOG_NAMESPACE`, `ROBOCOG_CONNECT`, ...), so a component started
//! by hand and one started by `robocog launch` are configured the same way.

use clap::{Args, ValueEnum};
use std::path::PathBuf;

/// The endpoint of the router `robocog launch` hosts when no port is given.
pub const DEFAULT_ROUTER: &str = "tcp/127.0.0.1:7447";
/// The namespace when none is given.
pub const DEFAULT_NAMESPACE: &str = "default";

/// How a component joins the bus.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Default)]
pub enum Mode {
    /// Connect to a router (the launcher's, or one named by `--connect`); all traffic goes through
    /// routers. The default: predictable, and no port opened by the component.
    #[default]
    Client,
    /// A zenoh peer: connects to the routers given, and directly to the other peers it learns of.
    Peer,
}

/// Connection flags shared by every binary.
#[derive(Debug, Clone, Args)]
pub struct ConnectArgs {
    /// Namespace of the deployment: keys live under robocog/<namespace>/. Two deployments with
    /// different namespaces never see each other's topics.
    #[arg(long, env = "ROBOCOG_NAMESPACE", default_value = DEFAULT_NAMESPACE, global = true)]
    pub namespace: String,

    /// zenoh endpoints to connect to (comma-separated), e.g. tcp/127.0.0.1:7447.
    /// Default: the launcher's router on this host, tcp/127.0.0.1:7447.
    #[arg(long, env = "ROBOCOG_CONNECT", value_delimiter = ',', global = true)]
    pub connect: Vec<String>,

    /// zenoh endpoints to listen on (comma-separated); needed only in peer mode, or to let other
    /// hosts reach this process.
    #[arg(long, env = "ROBOCOG_LISTEN", value_delimiter = ',', global = true)]
    pub listen: Vec<String>,

    /// A zenoh configuration file (JSON5). Its settings win over the defaults; --connect,
    /// --listen and --mode given explicitly win over the file.
    #[arg(long = "config", env = "ROBOCOG_ZENOH_CONFIG", global = true)]
    pub zenoh_config: Option<PathBuf>,

    /// client (through routers) or peer.
    #[arg(long, env = "ROBOCOG_MODE", value_enum, default_value_t = Mode::Client, global = true)]
    pub mode: Mode,

    /// Do not use shared memory for large payloads (it is used by default when both ends share a
    /// host).
    #[arg(long, env = "ROBOCOG_NO_SHM", global = true)]
    pub no_shm: bool,
}

impl Default for ConnectArgs {
    fn default() -> Self {
        Self {
            namespace: DEFAULT_NAMESPACE.to_string(),
            connect: Vec::new(),
            listen: Vec::new(),
            zenoh_config: None,
            mode: Mode::Client,
            no_shm: false,
        }
    }
}

impl ConnectArgs {
    /// Flags for a process joining the router at `endpoint` in namespace `ns`.
    pub fn to_router(endpoint: &str, ns: &str) -> Self {
        Self {
            namespace: ns.to_string(),
            connect: vec![endpoint.to_string()],
            ..Self::default()
        }
    }

    /// The endpoints this process will connect to.
    pub fn endpoints(&self) -> Vec<String> {
        if self.connect.is_empty() && self.zenoh_config.is_none() {
            vec![DEFAULT_ROUTER.to_string()]
        } else {
            self.connect.clone()
        }
    }

    /// The environment a child process needs to join the same bus the same way.
    pub fn to_env(&self) -> Vec<(String, String)> {
        let mut env = vec![
            ("ROBOCOG_NAMESPACE".to_string(), self.namespace.clone()),
            ("ROBOCOG_CONNECT".to_string(), self.endpoints().join(",")),
            (
                "ROBOCOG_MODE".to_string(),
                match self.mode {
                    Mode::Client => "client",
                    Mode::Peer => "peer",
                }
                .to_string(),
            ),
        ];
        if let Some(p) = &self.zenoh_config {
            env.push(("ROBOCOG_ZENOH_CONFIG".into(), p.display().to_string()));
        }
        if self.no_shm {
            env.push(("ROBOCOG_NO_SHM".into(), "true".into()));
        }
        env
    }

    /// The zenoh configuration these flags describe: multicast scouting off, shared memory on
    /// unless `--no-shm`, then the config file, then the explicit flags.
    pub fn zenoh_config(&self) -> Result<zenoh::Config, crate::bus::BusError> {
        use crate::bus::BusError;
        let cfg_err = |what: &str, e: zenoh::Error| BusError::Config(format!("{what}: {e}"));
        let mut config = match &self.zenoh_config {
            Some(path) => zenoh::Config::from_file(path).map_err(|e| {
                BusError::Config(format!("cannot read zenoh config {}: {e}", path.display()))
            })?,
            None => {
                let mut c = zenoh::Config::default();
                c.insert_json5("scouting/multicast/enabled", "false")
                    .map_err(|e| cfg_err("scouting", e))?;
                // A lost router is dialled again every second at most (zenoh's own back-off
                // reaches 4 s): the components are back within about a second of a restarted
                // router (`robocog launch` restarts its router when it dies).
                c.insert_json5(
                    "connect/retry",
                    r#"{ period_init_ms: 250, period_max_ms: 1000, period_increase_factor: 2.0 }"#,
                )
                .map_err(|e| cfg_err("connect/retry", e))?;
                c
            }
        };
        let mode = match self.mode {
            Mode::Client => "\"client\"",
            Mode::Peer => "\"peer\"",
        };
        config
            .insert_json5("mode", mode)
            .map_err(|e| cfg_err("mode", e))?;
        let endpoints = self.endpoints();
        if !endpoints.is_empty() {
            let list = serde_json::to_string(&endpoints).unwrap_or_default();
            config
                .insert_json5("connect/endpoints", &list)
                .map_err(|e| cfg_err("--connect", e))?;
        }
        if !self.listen.is_empty() {
            let list = serde_json::to_string(&self.listen).unwrap_or_default();
            config
                .insert_json5("listen/endpoints", &list)
                .map_err(|e| cfg_err("--listen", e))?;
        } else if self.mode == Mode::Peer && self.zenoh_config.is_none() {
            config
                .insert_json5("listen/endpoints", r#"["tcp/127.0.0.1:0"]"#)
                .map_err(|e| cfg_err("listen", e))?;
        }
        let shm = if self.no_shm { "false" } else { "true" };
        config
            .insert_json5("transport/shared_memory/enabled", shm)
            .map_err(|e| cfg_err("shared memory", e))?;
        Ok(config)
    }
}
