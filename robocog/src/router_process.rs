//! A machine's zenoh router as a process of its own (`robocog router`), started by the launcher
//! (and the agent) before any component, and started again on the same endpoint whenever it
//! dies: a fault in a link (zenoh's TLS link has a known unsound read/write path,
//! eclipse-zenoh/zenoh#2557) or a crash takes the router down, not the launcher. The machine's
//! components are zenoh clients that redial the endpoint (every second at most, see
//! `interfaces::args`) and declare their subscriptions, services and tokens again; the launcher
//! goes on supervising meanwhile.

use std::path::{Path, PathBuf};
use std::process::ExitStatus;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::time::Duration;

use tokio::sync::{mpsc, watch};

use crate::supervisor::{BoxFuture, spawn_process};

/// The line `robocog router` prints once it listens, followed by its loopback endpoint.
pub const LISTENING: &str = "listening on";

/// How long a router may take to listen.
const START_TIMEOUT: Duration = Duration::from_secs(30);
/// The pause before a dead router is started again, doubled while it keeps dying at once.
const RESTART_PAUSE: Duration = Duration::from_millis(100);
const RESTART_PAUSE_MAX: Duration = Duration::from_secs(5);
/// A router that ran this long before dying is started again after the shortest pause.
const STABLE: Duration = Duration::from_secs(30);

fn say(msg: impl std::fmt::Display) {
    eprintln!("robocog | {msg}");
}

/// A running router process, restarted when it dies until [`RouterProcess::stop`].
#[derive(Debug)]
pub struct RouterProcess {
    /// The loopback endpoint the machine's components join.
    pub endpoint: String,
    pid: Arc<AtomicU32>,
    stopping: Arc<AtomicBool>,
    supervisor: tokio::task::JoinHandle<()>,
    /// The configuration file its restarts read.
    file: PathBuf,
}

/// One start: its pid, its exit, and the endpoint it listens on.
struct Started {
    pid: u32,
    exit: watch::Receiver<Option<Option<ExitStatus>>>,
    endpoint: String,
}

/// Starts `robocog router --config file` and waits until it listens.
async fn start_once(file: &Path) -> anyhow::Result<Started> {
    let exe = std::env::current_exe()
        .map_err(|e| anyhow::anyhow!("cannot find the robocog binary to run the router: {e}"))?;
    let (listening_tx, mut listening_rx) = mpsc::channel::<String>(4);
    let on_line = move |line: String, to_stderr: bool| {
        if let Some(endpoint) = line.strip_prefix(LISTENING) {
            let _ = listening_tx.try_send(endpoint.trim().to_string());
        } else if to_stderr {
            eprintln!("router | {line}");
        } else {
            println!("router | {line}");
        }
    };
    let on_exit = |_status: Option<ExitStatus>| -> BoxFuture { Box::pin(async {}) };
    let args = vec![
        "router".to_string(),
        "--config".to_string(),
        file.display().to_string(),
    ];
    let spawned = spawn_process(&exe, &args, vec![], on_line, on_exit)?;
    let mut exit = spawned.exit.clone();
    let endpoint = tokio::select! {
        e = listening_rx.recv() => e.ok_or_else(|| anyhow::anyhow!("the router said nothing"))?,
        status = exit.wait_for(|s| s.is_some()) => {
            let status = status.map(|s| *s).ok().flatten();
            anyhow::bail!(
                "the router stopped before it listened ({})",
                crate::supervisor::describe_status(status.flatten())
            )
        }
        () = wall_sleep(START_TIMEOUT) => {
            kill(spawned.pid, nix::sys::signal::Signal::SIGKILL);
            anyhow::bail!("the router did not listen within {START_TIMEOUT:?}")
        }
    };
    say(format!(
        "started router (pid {}): {} {}",
        spawned.pid,
        exe.display(),
        args.join(" ")
    ));
    Ok(Started {
        pid: spawned.pid,
        exit: spawned.exit,
        endpoint,
    })
}

#[expect(
    clippy::disallowed_methods,
    reason = "the launcher supervises real processes on the wall"
)]
async fn wall_sleep(d: Duration) {
    tokio::time::sleep(d).await;
}

#[expect(
    clippy::disallowed_methods,
    reason = "the launcher supervises real processes on the wall"
)]
fn wall_now() -> std::time::Instant {
    std::time::Instant::now()
}

fn kill(pid: u32, signal: nix::sys::signal::Signal) {
    let _ = nix::sys::signal::kill(nix::unistd::Pid::from_raw(pid as i32), signal);
}

/// `config`'s listen endpoints with `asked` (port 0: any free port) replaced by `got`, the
/// endpoint the first router took: a restarted router must listen where the clients redial.
fn pin_listen(config: &mut zenoh::Config, asked: &str, got: &str) -> anyhow::Result<()> {
    let list: Vec<String> = config
        .get_json("listen/endpoints")
        .ok()
        .and_then(|j| serde_json::from_str(&j).ok())
        .unwrap_or_default();
    let list: Vec<String> = list
        .into_iter()
        .map(|e| if e == asked { got.to_string() } else { e })
        .collect();
    config
        .insert_json5("listen/endpoints", &serde_json::to_string(&list)?)
        .map_err(|e| anyhow::anyhow!("the router's listen endpoints: {e}"))
}

impl RouterProcess {
    /// Writes `config` (a router listening on `local_listen` among others) to a file of this
    /// process's own in the temporary folder, starts the router and returns once it listens; a
    /// supervisor restarts it whenever it dies.
    pub async fn start(
        mut config: zenoh::Config,
        local_listen: &str,
    ) -> anyhow::Result<RouterProcess> {
        let file =
            std::env::temp_dir().join(format!("robocog-router-{}.json5", std::process::id()));
        let write = |config: &zenoh::Config| {
            std::fs::write(&file, config.to_string())
                .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", file.display()))
        };
        write(&config)?;
        let first = start_once(&file).await?;
        let endpoint = first.endpoint.clone();
        pin_listen(&mut config, local_listen, &endpoint)?;
        write(&config)?;
        let pid = Arc::new(AtomicU32::new(first.pid));
        let stopping = Arc::new(AtomicBool::new(false));
        let supervisor = {
            let file = file.clone();
            let pid = pid.clone();
            let stopping = stopping.clone();
            let endpoint = endpoint.clone();
            tokio::spawn(async move {
                let mut current = first;
                let mut pause = RESTART_PAUSE;
                loop {
                    let started_at = wall_now();
                    let _ = current.exit.wait_for(|s| s.is_some()).await;
                    if stopping.load(Ordering::SeqCst) {
                        return;
                    }
                    let status = *current.exit.borrow();
                    if started_at.elapsed() >= STABLE {
                        pause = RESTART_PAUSE;
                    }
                    say(format!(
                        "the router (pid {}) stopped ({}): starting it again on {endpoint}; the components reconnect",
                        current.pid,
                        crate::supervisor::describe_status(status.flatten())
                    ));
                    loop {
                        wall_sleep(pause).await;
                        pause = (pause * 2).min(RESTART_PAUSE_MAX);
                        if stopping.load(Ordering::SeqCst) {
                            return;
                        }
                        match start_once(&file).await {
                            Ok(s) => {
                                pid.store(s.pid, Ordering::SeqCst);
                                current = s;
                                break;
                            }
                            Err(e) => say(format!(
                                "cannot start the router again: {e:#}; trying again in {pause:?}"
                            )),
                        }
                    }
                }
            })
        };
        Ok(RouterProcess {
            endpoint,
            pid,
            stopping,
            supervisor,
            file,
        })
    }

    /// The router's current pid.
    pub fn pid(&self) -> u32 {
        self.pid.load(Ordering::SeqCst)
    }

    /// Stops the router (SIGTERM, SIGKILL after 5 s) and its supervision.
    pub async fn stop(self) {
        self.stopping.store(true, Ordering::SeqCst);
        let pid = self.pid();
        kill(pid, nix::sys::signal::Signal::SIGTERM);
        let deadline = wall_now() + Duration::from_secs(5);
        while std::path::Path::new(&format!("/proc/{pid}")).exists() && wall_now() < deadline {
            wall_sleep(Duration::from_millis(20)).await;
        }
        if std::path::Path::new(&format!("/proc/{pid}")).exists() {
            kill(pid, nix::sys::signal::Signal::SIGKILL);
        }
        self.supervisor.abort();
        let _ = std::fs::remove_file(&self.file);
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn a_restarted_router_listens_where_the_first_one_did() {
        let mut c = zenoh::Config::default();
        c.insert_json5(
            "listen/endpoints",
            r#"["tcp/127.0.0.1:0", "tls/10.0.0.2:7447"]"#,
        )
        .unwrap();
        pin_listen(&mut c, "tcp/127.0.0.1:0", "tcp/127.0.0.1:40123").unwrap();
        let got: Vec<String> =
            serde_json::from_str(&c.get_json("listen/endpoints").unwrap()).unwrap();
        assert_eq!(got, ["tcp/127.0.0.1:40123", "tls/10.0.0.2:7447"]);
    }
}
