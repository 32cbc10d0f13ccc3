//! `robocog launch`: host the router, start the graph in dependency order, watch it, restart what
//! crashes, and stop everything cleanly.
//!
//! The launcher is the parent of every component. Each child runs in its own process group (so a
//! terminal's Ctrl-C reaches the launcher only, and stopping a child also stops what it started),
//! and dies with the launcher even if the launcher is killed with SIGKILL (`PR_SET_PDEATHSIG`).
//! A component is *up* when its liveliness token appears on the bus.
//!
//! Each component gets a state folder, `<state_dir>/<component>` in ROBOCOG_STATE_DIR (created
//! by the component if it keeps state): it outlives the component's restarts, so a restarted
//! component takes up where it was (the deep representation recovers its world model there). A
//! launch starts afresh (an earlier launch's folder is moved aside to `<namespace>.previous`)
//! unless `--resume`; a launch that ends cleanly removes its folder, one that fails keeps it for
//! a look and for `--resume`.
//!
//! A component that exits with [`EX_CONFIG`] (it cannot start for a reason a restart cannot fix:
//! a missing file, no such device) or [`EX_USAGE`] (flags it cannot parse) is not restarted,
//! whatever its policy: if it is required, the graph stops at once with its message and the
//! launcher exits with [`EX_CONFIG`].

use crate::manifest::{Component, Manifest, RestartPolicy};
use interfaces::liveliness::{self, Token};
use interfaces::node::{EX_CONFIG, EX_USAGE};
use nix::sys::signal::{Signal, killpg};
use nix::unistd::Pid;
use std::collections::{HashMap, VecDeque};
use std::process::{ExitStatus, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::io::{AsyncBufReadExt, BufReader};
use tokio::process::Command;
use tokio::sync::{mpsc, watch};

/// How `launch` runs.
#[derive(Debug, Clone)]
pub struct LaunchOptions {
    pub namespace: String,
    /// The endpoint the launcher's router listens on (`tcp/127.0.0.1:0` for any free port).
    pub router: String,
    pub color: bool,
    /// The graph's state folder for this namespace: each component keeps its state in
    /// `<state_dir>/<component>` (ROBOCOG_STATE_DIR), across its restarts.
    pub state_dir: std::path::PathBuf,
    /// Keep what an earlier launch left in `state_dir` (else it is moved aside).
    pub resume: bool,
}

const PALETTE: [u8; 12] = [36, 32, 33, 35, 34, 31, 96, 92, 93, 95, 94, 91];
const TAIL_LINES: usize = 20;
const MAX_BACKOFF: Duration = Duration::from_secs(30);

#[derive(Debug)]
enum Event {
    Up {
        name: String,
        pid: u32,
    },
    Exited {
        name: String,
        generation: u64,
        status: Option<ExitStatus>,
    },
    RestartDue {
        name: String,
    },
    Stop {
        reason: String,
    },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    Pending,
    Starting { deadline: Instant },
    Up,
    Backoff,
    Exited,
    Failed,
}

struct Child {
    spec: Component,
    binary: std::path::PathBuf,
    state: State,
    pid: Option<u32>,
    generation: u64,
    restarts: u32,
    started: Instant,
    exit: Option<watch::Receiver<Option<Option<ExitStatus>>>>,
    tail: Arc<Mutex<VecDeque<String>>>,
    prefix: String,
}

fn prefix(name: &str, width: usize, index: usize, color: bool) -> String {
    if color {
        format!(
            "\x1b[{}m{name:>width$}\x1b[0m |",
            PALETTE[index % PALETTE.len()]
        )
    } else {
        format!("{name:>width$} |")
    }
}

/// Say something as the launcher.
fn say(msg: impl std::fmt::Display) {
    eprintln!("robocog | {msg}");
}

fn describe_status(status: Option<ExitStatus>) -> String {
    use std::os::unix::process::ExitStatusExt;
    match status {
        None => "exit status unknown".into(),
        Some(s) => match (s.code(), s.signal()) {
            (Some(c), _) => format!("exit code {c}"),
            (None, Some(sig)) => {
                let name = Signal::try_from(sig).map(|s| s.as_str()).unwrap_or("?");
                format!("killed by signal {sig} ({name})")
            }
            _ => "exited".into(),
        },
    }
}

fn failed(status: Option<ExitStatus>) -> bool {
    status.is_none_or(|s| !s.success())
}

/// Whether the component said it cannot start for a reason a restart cannot fix.
fn misconfigured(status: Option<ExitStatus>) -> bool {
    status
        .and_then(|s| s.code())
        .is_some_and(|c| c == i32::from(EX_CONFIG) || c == i32::from(EX_USAGE))
}

/// Run the graph until it completes, fails for good, or is asked to stop. Returns the process
/// exit code: 0 on a clean stop or completion, 1 when a required component failed,
/// [`EX_CONFIG`] when a required component cannot start for a reason a restart cannot fix.
pub async fn launch(manifest: Manifest, opts: LaunchOptions) -> anyhow::Result<i32> {
    let order: Vec<String> = manifest
        .start_order()
        .map_err(|p| anyhow::anyhow!("{p}"))?
        .into_iter()
        .map(|c| c.name.clone())
        .collect();

    // The router every component joins.
    let (router, endpoint) = interfaces::router::open_router(&opts.router).await?;
    let connect = interfaces::ConnectArgs::to_router(&endpoint, &opts.namespace);
    say(format!(
        "graph {:?}: router {endpoint}, namespace {}, {} components",
        manifest.name,
        opts.namespace,
        manifest.components.len()
    ));

    prepare_state_dir(&opts.state_dir, opts.resume)?;
    say(format!(
        "component state in {}{}",
        opts.state_dir.display(),
        if opts.resume { " (resumed)" } else { "" }
    ));

    let (tx, mut rx) = mpsc::channel::<Event>(1024);

    // Components are up when their liveliness token appears.
    let tokens = router
        .liveliness()
        .declare_subscriber(liveliness::components(&opts.namespace))
        .history(true)
        .with(zenoh::handlers::FifoChannel::new(1024))
        .await
        .map_err(|e| anyhow::anyhow!("cannot watch liveliness: {e}"))?;
    {
        let tx = tx.clone();
        let ns = opts.namespace.clone();
        tokio::spawn(async move {
            while let Ok(sample) = tokens.recv_async().await {
                if sample.kind() != zenoh::sample::SampleKind::Put {
                    continue;
                }
                if let Some(Token::Component { name, pid, .. }) =
                    liveliness::parse(&ns, sample.key_expr().as_str())
                    && tx.send(Event::Up { name, pid }).await.is_err()
                {
                    return;
                }
            }
        });
    }
    // Ctrl-C and SIGTERM stop the graph.
    {
        let tx = tx.clone();
        tokio::spawn(async move {
            use tokio::signal::unix::{SignalKind, signal};
            let (Ok(mut term), Ok(mut int)) = (
                signal(SignalKind::terminate()),
                signal(SignalKind::interrupt()),
            ) else {
                return;
            };
            let reason = tokio::select! {
                _ = term.recv() => "SIGTERM",
                _ = int.recv() => "interrupted",
            };
            let _ = tx
                .send(Event::Stop {
                    reason: reason.into(),
                })
                .await;
        });
    }

    let width = manifest
        .components
        .iter()
        .map(|c| c.name.len())
        .max()
        .unwrap_or(8)
        .max(7);
    let mut children: HashMap<String, Child> = HashMap::new();
    for (i, c) in manifest.components.iter().enumerate() {
        let binary = c
            .resolve_binary()
            .ok_or_else(|| anyhow::anyhow!("{}: unknown binary {:?}", c.origin, c.binary))?;
        children.insert(
            c.name.clone(),
            Child {
                spec: c.clone(),
                binary,
                state: State::Pending,
                pid: None,
                generation: 0,
                restarts: 0,
                started: Instant::now(),
                exit: None,
                tail: Arc::new(Mutex::new(VecDeque::new())),
                prefix: prefix(&c.name, width, i, opts.color),
            },
        );
    }

    let mut exit_code: Option<i32> = None;
    let mut tick = tokio::time::interval(Duration::from_millis(100));
    loop {
        // Start whatever has all its dependencies up.
        for name in &order {
            let ready = {
                let c = &children[name];
                c.state == State::Pending
                    && c.spec
                        .depends_on
                        .iter()
                        .all(|d| children.get(d).is_some_and(|d| d.state == State::Up))
            };
            if ready
                && let Some(c) = children.get_mut(name)
                && let Err(e) = spawn(c, &connect, &opts.state_dir, &tx)
            {
                say(format!("cannot start {name}: {e:#}"));
                exit_code = Some(1);
            }
        }
        if exit_code.is_some() {
            break;
        }
        let event = tokio::select! {
            e = rx.recv() => e,
            _ = tick.tick() => None,
        };
        match event {
            Some(Event::Up { name, pid }) => {
                if let Some(c) = children.get_mut(&name)
                    && c.pid == Some(pid)
                    && matches!(c.state, State::Starting { .. })
                {
                    c.state = State::Up;
                    say(format!(
                        "{name} is up (pid {pid}, {} ms)",
                        c.started.elapsed().as_millis()
                    ));
                }
            }
            Some(Event::Exited {
                name,
                generation,
                status,
            }) => {
                let Some(c) = children.get_mut(&name) else {
                    continue;
                };
                if c.generation != generation {
                    continue;
                }
                let what = describe_status(status);
                if c.spec.completes_graph && !failed(status) {
                    say(format!("{name} completed ({what}): the graph is done"));
                    exit_code = Some(0);
                    c.state = State::Exited;
                    c.pid = None;
                    continue;
                }
                let restart = match c.spec.restart {
                    RestartPolicy::Never => false,
                    RestartPolicy::OnFailure => failed(status),
                    RestartPolicy::Always => true,
                };
                c.pid = None;
                if misconfigured(status) {
                    c.state = State::Failed;
                    let tail = last_lines(c);
                    if c.spec.required {
                        say(format!(
                            "{name} cannot start ({what}: its configuration, a file or a device it needs; a restart would not fix it): stopping the graph{tail}"
                        ));
                        exit_code = Some(i32::from(EX_CONFIG));
                    } else {
                        say(format!(
                            "{name} cannot start ({what}: its configuration, a file or a device it needs); it is not required, the graph goes on without it{tail}"
                        ));
                    }
                } else if restart && c.restarts < c.spec.max_restarts {
                    c.restarts += 1;
                    let delay =
                        (c.spec.backoff * 2u32.saturating_pow(c.restarts - 1)).min(MAX_BACKOFF);
                    say(format!(
                        "{name} stopped ({what}); restart {}/{} in {} ms",
                        c.restarts,
                        c.spec.max_restarts,
                        delay.as_millis()
                    ));
                    c.state = State::Backoff;
                    let tx = tx.clone();
                    tokio::spawn(async move {
                        tokio::time::sleep(delay).await;
                        let _ = tx.send(Event::RestartDue { name }).await;
                    });
                } else if restart || failed(status) {
                    c.state = State::Failed;
                    let tail = last_lines(c);
                    if c.spec.required {
                        say(format!(
                            "{name} failed for good ({what}, after {} restarts); stopping the graph{tail}",
                            c.restarts
                        ));
                        exit_code = Some(1);
                    } else {
                        say(format!(
                            "{name} failed for good ({what}); it is not required, the graph goes on{tail}"
                        ));
                    }
                } else {
                    c.state = State::Exited;
                    say(format!("{name} exited ({what})"));
                }
            }
            Some(Event::RestartDue { name }) => {
                if let Some(c) = children.get_mut(&name)
                    && c.state == State::Backoff
                    && let Err(e) = spawn(c, &connect, &opts.state_dir, &tx)
                {
                    say(format!("cannot restart {name}: {e:#}"));
                    c.state = State::Failed;
                    if c.spec.required {
                        exit_code = Some(1);
                    }
                }
            }
            Some(Event::Stop { reason }) => {
                say(format!("{reason}: stopping the graph"));
                exit_code = Some(0);
            }
            None => {
                let now = Instant::now();
                for c in children.values_mut() {
                    if let State::Starting { deadline } = c.state
                        && now > deadline
                    {
                        say(format!(
                            "{} never came up: no liveliness token within {:.1} s (is it a robocog component, and can it reach the router?){}",
                            c.spec.name,
                            c.spec.ready_timeout.as_secs_f64(),
                            last_lines(c)
                        ));
                        c.state = State::Failed;
                        exit_code = Some(1);
                    }
                }
            }
        }
        if exit_code.is_some() {
            break;
        }
    }

    stop_all(&manifest, &mut children).await;
    drop(router);
    let code = exit_code.unwrap_or(0);
    if code == 0 {
        if let Err(e) = std::fs::remove_dir_all(&opts.state_dir)
            && e.kind() != std::io::ErrorKind::NotFound
        {
            say(format!(
                "cannot remove the state folder {}: {e}",
                opts.state_dir.display()
            ));
        }
        // The graph's folder too, when no other namespace has state in it.
        if let Some(graph) = opts.state_dir.parent() {
            let _ = std::fs::remove_dir(graph);
        }
    } else {
        say(format!(
            "the components' state stays in {} (robocog launch --resume takes it up)",
            opts.state_dir.display()
        ));
    }
    Ok(code)
}

/// Make `dir` ready for this launch: kept with `resume`, else an earlier launch's moved aside.
fn prepare_state_dir(dir: &std::path::Path, resume: bool) -> anyhow::Result<()> {
    use anyhow::Context;
    if !resume && dir.exists() {
        let mut aside = dir.as_os_str().to_owned();
        aside.push(".previous");
        let aside = std::path::PathBuf::from(aside);
        if aside.exists() {
            std::fs::remove_dir_all(&aside)
                .with_context(|| format!("cannot remove {}", aside.display()))?;
        }
        std::fs::rename(dir, &aside).with_context(|| {
            format!(
                "cannot move an earlier launch's state aside to {}",
                aside.display()
            )
        })?;
        say(format!(
            "an earlier launch left state in {}: moved aside to {} (--resume takes it up)",
            dir.display(),
            aside.display()
        ));
    }
    std::fs::create_dir_all(dir)
        .with_context(|| format!("cannot create the state folder {}", dir.display()))?;
    Ok(())
}

fn last_lines(c: &Child) -> String {
    let tail = c.tail.lock().unwrap_or_else(|p| p.into_inner());
    if tail.is_empty() {
        return String::new();
    }
    let mut s = format!("\n  last lines of {}:", c.spec.name);
    for l in tail.iter() {
        s.push_str("\n    ");
        s.push_str(l);
    }
    s
}

/// Ask the kernel to SIGKILL the child when the launcher dies, whatever the reason.
#[allow(unsafe_code)]
fn die_with_parent(cmd: &mut Command) {
    // SAFETY: the closure runs in the forked child before exec and only calls prctl(2), which is
    // async-signal-safe, and getppid(2).
    unsafe {
        cmd.pre_exec(|| {
            nix::sys::prctl::set_pdeathsig(Signal::SIGKILL).map_err(std::io::Error::from)?;
            // The launcher may already be gone (it died between fork and prctl).
            if nix::unistd::getppid() == Pid::from_raw(1) {
                return Err(std::io::Error::other("the launcher is gone"));
            }
            Ok(())
        });
    }
}

fn spawn(
    c: &mut Child,
    connect: &interfaces::ConnectArgs,
    state_dir: &std::path::Path,
    tx: &mpsc::Sender<Event>,
) -> anyhow::Result<()> {
    let mut cmd = Command::new(&c.binary);
    cmd.args(&c.spec.args)
        .envs(connect.to_env())
        .env("ROBOCOG_COMPONENT", &c.spec.name)
        .env("ROBOCOG_STATE_DIR", state_dir.join(&c.spec.name))
        .envs(&c.spec.env)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .process_group(0)
        .kill_on_drop(false);
    die_with_parent(&mut cmd);
    let mut child = cmd
        .spawn()
        .map_err(|e| anyhow::anyhow!("cannot run {}: {e}", c.binary.display()))?;
    let pid = child.id().unwrap_or(0);
    c.generation += 1;
    c.pid = Some(pid);
    c.started = Instant::now();
    c.state = State::Starting {
        deadline: Instant::now() + c.spec.ready_timeout,
    };
    say(format!(
        "started {} (pid {pid}): {} {}",
        c.spec.name,
        c.binary.display(),
        c.spec.args.join(" ")
    ));

    for (stream, to_stderr) in [
        (
            child
                .stdout
                .take()
                .map(|s| Box::new(s) as Box<dyn tokio::io::AsyncRead + Unpin + Send>),
            false,
        ),
        (
            child
                .stderr
                .take()
                .map(|s| Box::new(s) as Box<dyn tokio::io::AsyncRead + Unpin + Send>),
            true,
        ),
    ] {
        let Some(stream) = stream else { continue };
        let prefix = c.prefix.clone();
        let tail = c.tail.clone();
        tokio::spawn(async move {
            let mut lines = BufReader::new(stream).split(b'\n');
            while let Ok(Some(line)) = lines.next_segment().await {
                let line = String::from_utf8_lossy(&line).trim_end().to_string();
                if to_stderr {
                    eprintln!("{prefix} {line}");
                } else {
                    println!("{prefix} {line}");
                }
                let mut t = tail.lock().unwrap_or_else(|p| p.into_inner());
                if t.len() == TAIL_LINES {
                    t.pop_front();
                }
                t.push_back(line);
            }
        });
    }

    let (exit_tx, exit_rx) = watch::channel(None);
    c.exit = Some(exit_rx);
    let tx = tx.clone();
    let name = c.spec.name.clone();
    let generation = c.generation;
    tokio::spawn(async move {
        let status = child.wait().await.ok();
        let _ = exit_tx.send(Some(status));
        let _ = tx
            .send(Event::Exited {
                name,
                generation,
                status,
            })
            .await;
    });
    Ok(())
}

/// Stop every running child, dependents before their dependencies: SIGTERM to its process group,
/// then SIGKILL after its stop time-out. Finally SIGKILL every group, so nothing is left behind.
async fn stop_all(manifest: &Manifest, children: &mut HashMap<String, Child>) {
    // Depth in the dependency graph: leaves (no dependents) stop first.
    let mut depth: HashMap<String, usize> = HashMap::new();
    if let Ok(order) = manifest.start_order() {
        for c in order {
            let d = c
                .depends_on
                .iter()
                .filter_map(|d| depth.get(d))
                .max()
                .map_or(0, |d| d + 1);
            depth.insert(c.name.clone(), d);
        }
    }
    let max_depth = depth.values().copied().max().unwrap_or(0);
    let mut groups = Vec::new();
    for level in (0..=max_depth).rev() {
        let mut waiting = Vec::new();
        for c in children.values_mut() {
            if depth.get(&c.spec.name).copied().unwrap_or(0) != level {
                continue;
            }
            if let Some(pid) = c.pid.take() {
                groups.push(pid);
                let _ = killpg(Pid::from_raw(pid as i32), Signal::SIGTERM);
                waiting.push((
                    c.spec.name.clone(),
                    pid,
                    c.spec.stop_timeout,
                    c.exit.clone(),
                ));
            }
        }
        let waits = waiting
            .into_iter()
            .map(|(name, pid, grace, exit)| async move {
                let Some(mut exit) = exit else { return };
                let done = tokio::time::timeout(grace, async {
                    let _ = exit.wait_for(|s| s.is_some()).await.map(|_| ());
                })
                .await;
                if done.is_err() {
                    say(format!(
                        "{name} ignored SIGTERM for {:.1} s: SIGKILL",
                        grace.as_secs_f64()
                    ));
                    let _ = killpg(Pid::from_raw(pid as i32), Signal::SIGKILL);
                    let _ = tokio::time::timeout(Duration::from_secs(5), async {
                        let _ = exit.wait_for(|s| s.is_some()).await.map(|_| ());
                    })
                    .await;
                }
            });
        futures_join_all(waits).await;
    }
    // Anything a component left in its group goes too.
    for pid in groups {
        let _ = killpg(Pid::from_raw(pid as i32), Signal::SIGKILL);
    }
    say("all components stopped");
}

async fn futures_join_all<F: std::future::Future<Output = ()> + Send + 'static>(
    futures: impl IntoIterator<Item = F>,
) {
    let handles: Vec<_> = futures.into_iter().map(tokio::spawn).collect();
    for h in handles {
        let _ = h.await;
    }
}
