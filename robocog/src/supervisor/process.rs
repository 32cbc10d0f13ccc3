//! Component processes on this machine: started in their own process group, killed with the
//! launcher, their output prefixed and kept, their exit reported.

use super::{Child, Event, State, TAIL_LINES, say};
use nix::sys::signal::Signal;
use nix::unistd::Pid;
use std::collections::VecDeque;
use std::process::{ExitStatus, Stdio};
use std::sync::{Arc, Mutex};
use std::time::Instant;
use tokio::io::{AsyncBufReadExt, BufReader};
use tokio::process::Command;
use tokio::sync::{mpsc, watch};

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

/// What a process's exit runs.
pub(crate) type BoxFuture = std::pin::Pin<Box<dyn std::future::Future<Output = ()> + Send>>;

/// A process started by [`spawn_process`].
pub(crate) struct Spawned {
    pub pid: u32,
    /// Becomes `Some(status)` when it has exited (`None` inside: its status is unknown).
    pub exit: watch::Receiver<Option<Option<ExitStatus>>>,
}

/// Start `binary` as a component process: its own process group, killed with its parent, stdin
/// closed, every line it writes handed to `on_line` (with whether it came on stderr), and
/// `on_exit` called with its status once it has exited.
pub(crate) fn spawn_process(
    binary: &std::path::Path,
    args: &[String],
    env: Vec<(String, String)>,
    on_line: impl Fn(String, bool) + Send + Sync + 'static,
    on_exit: impl FnOnce(Option<ExitStatus>) -> BoxFuture + Send + 'static,
) -> anyhow::Result<Spawned> {
    let mut cmd = Command::new(binary);
    cmd.args(args)
        .envs(env)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .process_group(0)
        .kill_on_drop(false);
    die_with_parent(&mut cmd);
    let mut child = cmd
        .spawn()
        .map_err(|e| anyhow::anyhow!("cannot run {}: {e}", binary.display()))?;
    let pid = child.id().unwrap_or(0);
    let on_line = Arc::new(on_line);
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
        let on_line = on_line.clone();
        tokio::spawn(async move {
            let mut lines = BufReader::new(stream).split(b'\n');
            while let Ok(Some(line)) = lines.next_segment().await {
                on_line(
                    String::from_utf8_lossy(&line).trim_end().to_string(),
                    to_stderr,
                );
            }
        });
    }
    let (exit_tx, exit_rx) = watch::channel(None);
    tokio::spawn(async move {
        let status = child.wait().await.ok();
        let _ = exit_tx.send(Some(status));
        on_exit(status).await;
    });
    Ok(Spawned { pid, exit: exit_rx })
}

#[expect(
    clippy::disallowed_methods,
    reason = "the launcher supervises real processes: their start time and deadline are on the wall"
)]
pub(super) fn spawn(
    c: &mut Child,
    connect: &interfaces::ConnectArgs,
    state_dir: &std::path::Path,
    tx: &mpsc::Sender<Event>,
) -> anyhow::Result<()> {
    let mut env = connect.to_env();
    env.push(("ROBOCOG_COMPONENT".into(), c.spec.name.clone()));
    env.push((
        "ROBOCOG_STATE_DIR".into(),
        state_dir.join(&c.spec.name).display().to_string(),
    ));
    env.extend(c.spec.env.iter().map(|(k, v)| (k.clone(), v.clone())));
    let prefix = c.prefix.clone();
    let tail = c.tail.clone();
    let on_line = move |line: String, to_stderr: bool| {
        if to_stderr {
            eprintln!("{prefix} {line}");
        } else {
            println!("{prefix} {line}");
        }
        push_tail(&tail, line);
    };
    let tx = tx.clone();
    let name = c.spec.name.clone();
    let generation = c.generation + 1;
    let on_exit = move |status: Option<ExitStatus>| -> BoxFuture {
        Box::pin(async move {
            let _ = tx
                .send(Event::Exited {
                    name,
                    generation,
                    status,
                })
                .await;
        })
    };
    let spawned = spawn_process(&c.binary, &c.spec.args, env, on_line, on_exit)?;
    let pid = spawned.pid;
    c.generation = generation;
    c.pid = Some(pid);
    c.started = Instant::now();
    c.state = State::Starting {
        deadline: Instant::now() + c.spec.ready_timeout,
    };
    c.exit = Some(spawned.exit);
    say(format!(
        "started {} (pid {pid}): {} {}",
        c.spec.name,
        c.binary.display(),
        c.spec.args.join(" ")
    ));
    Ok(())
}

/// Keep `line` among the last lines of a component (shown when it fails).
pub(super) fn push_tail(tail: &Mutex<VecDeque<String>>, line: String) {
    let mut t = tail.lock().unwrap_or_else(|p| p.into_inner());
    if t.len() == TAIL_LINES {
        t.pop_front();
    }
    t.push_back(line);
}
