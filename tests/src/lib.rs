#![allow(clippy::unwrap_used, clippy::expect_used)] // test support: a panic is how a test fails
//! Helpers for the process-and-bus tests: find the built binaries, give every test a fresh
//! namespace and a router on a free port, and wait for things with a time-out, always.
#![expect(
    clippy::disallowed_methods,
    reason = "process tests wait on real processes, with a time-out on every wait"
)]

pub mod netns;

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Output, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

/// A built binary of the workspace, next to the test executable's folder.
pub fn bin(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    let mut dir = exe.parent().expect("test dir").to_path_buf();
    if dir.ends_with("deps") {
        dir.pop();
    }
    let p = dir.join(name);
    assert!(
        p.is_file(),
        "{} is not built: build the workspace's binaries first (scripts/test does)",
        p.display()
    );
    p
}

/// A simulated Kinect's live fakenect dump folder for one test, in shared memory (`/dev/shm`):
/// 45 MB/s of frame files written and removed do not belong on a disk. Removed when dropped.
pub struct KinectDump {
    pub path: PathBuf,
}

/// A fresh [`KinectDump`] named after `tag`.
pub fn kinect_dump(tag: &str) -> KinectDump {
    let root = Path::new("/dev/shm");
    let base = if root.is_dir() {
        root.to_path_buf()
    } else {
        std::env::temp_dir()
    };
    let path = base.join(format!("robocog-{}", unique_namespace(tag)));
    std::fs::create_dir_all(&path).expect("kinect dump dir");
    KinectDump { path }
}

impl Drop for KinectDump {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.path);
    }
}

/// A namespace no other test (or deployment) uses.
pub fn unique_namespace(tag: &str) -> String {
    static N: AtomicU32 = AtomicU32::new(0);
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.subsec_nanos())
        .unwrap_or(0);
    format!(
        "test-{tag}-{}-{}-{nanos}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    )
}

/// Scratch folders older than this are removed by the next test run that makes one: a failed
/// run's files stay long enough to be read, and recordings do not pile up in the temp dir.
const SCRATCH_KEEP: Duration = Duration::from_secs(3600);

/// A scratch folder for one test, under `<temp>/robocog-tests/<ns>`. The first call in a test
/// process removes the folders of earlier runs older than [`SCRATCH_KEEP`] (no test lives that
/// long: nextest stops a hung one after 5 min).
pub fn scratch(ns: &str) -> PathBuf {
    static PRUNED: std::sync::Once = std::sync::Once::new();
    let root = std::env::temp_dir().join("robocog-tests");
    PRUNED.call_once(|| prune_scratch(&root));
    let d = root.join(ns);
    std::fs::create_dir_all(&d).expect("scratch dir");
    d
}

fn prune_scratch(root: &Path) {
    let Ok(entries) = std::fs::read_dir(root) else {
        return;
    };
    for entry in entries.flatten() {
        let old = entry
            .metadata()
            .and_then(|m| m.modified())
            .ok()
            .and_then(|t| t.elapsed().ok())
            .is_some_and(|age| age > SCRATCH_KEEP);
        if old {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
}

/// Write a manifest into `dir`, with `@FIXTURE@` replaced by the fixture node's path.
pub fn write_manifest(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    let fixture = bin("fixture_node");
    std::fs::write(
        &p,
        text.replace("@FIXTURE@", &fixture.display().to_string()),
    )
    .expect("write manifest");
    p
}

/// Lines a process printed (stdout and stderr), collected by background threads.
#[derive(Clone, Default)]
pub struct Lines {
    inner: Arc<(Mutex<Vec<String>>, Condvar)>,
}

impl Lines {
    fn follow(&self, stream: impl std::io::Read + Send + 'static) {
        let me = self.clone();
        std::thread::Builder::new()
            .name("test-output".into())
            .spawn(move || {
                for line in BufReader::new(stream).lines().map_while(Result::ok) {
                    let (m, cv) = &*me.inner;
                    m.lock().unwrap().push(line);
                    cv.notify_all();
                }
            })
            .expect("spawn reader");
    }
    /// Every line so far.
    pub fn all(&self) -> Vec<String> {
        self.inner.0.lock().unwrap().clone()
    }
    /// Wait until a line satisfies `pred`, at most `timeout`; panics with the output otherwise.
    pub fn wait_for(&self, what: &str, timeout: Duration, pred: impl Fn(&str) -> bool) -> String {
        let deadline = Instant::now() + timeout;
        let (m, cv) = &*self.inner;
        let mut lines = m.lock().unwrap();
        loop {
            if let Some(l) = lines.iter().find(|l| pred(l)) {
                return l.clone();
            }
            let now = Instant::now();
            if now >= deadline {
                panic!(
                    "timed out after {timeout:?} waiting for {what}; output so far:\n{}",
                    lines.join("\n")
                );
            }
            lines = cv.wait_timeout(lines, deadline - now).unwrap().0;
        }
    }
    /// Wait until `pred` holds over all the lines so far, at most `timeout`; panics with the
    /// output otherwise.
    pub fn wait_until(&self, what: &str, timeout: Duration, pred: impl Fn(&[String]) -> bool) {
        let deadline = Instant::now() + timeout;
        let (m, cv) = &*self.inner;
        let mut lines = m.lock().unwrap();
        loop {
            if pred(&lines) {
                return;
            }
            let now = Instant::now();
            if now >= deadline {
                panic!(
                    "timed out after {timeout:?} waiting for {what}; output so far:\n{}",
                    lines.join("\n")
                );
            }
            lines = cv.wait_timeout(lines, deadline - now).unwrap().0;
        }
    }

    /// How many lines satisfy `pred` now.
    pub fn count(&self, pred: impl Fn(&str) -> bool) -> usize {
        self.inner
            .0
            .lock()
            .unwrap()
            .iter()
            .filter(|l| pred(l))
            .count()
    }
}

/// A running `robocog launch`, with a router on a free port and a fresh namespace.
pub struct Launch {
    pub child: Child,
    pub namespace: String,
    pub endpoint: String,
    pub lines: Lines,
}

impl Launch {
    pub fn start(manifest: &Path, namespace: &str, extra: &[&str]) -> Launch {
        let mut child = Command::new(bin("robocog"))
            .arg("launch")
            .arg(manifest)
            .args([
                "--namespace",
                namespace,
                "--router",
                "tcp/127.0.0.1:0",
                "--color",
                "never",
            ])
            // The components' state in the test's scratch folder, not in the user's.
            .arg("--state-root")
            .arg(scratch(namespace).join("state"))
            .args(extra)
            // `ROBOCOG_TEST_LOG` (a `RUST_LOG` filter) to see more of a graph under test.
            .env(
                "RUST_LOG",
                std::env::var("ROBOCOG_TEST_LOG").unwrap_or_else(|_| "info".into()),
            )
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start robocog launch");
        let lines = Lines::default();
        lines.follow(child.stdout.take().expect("stdout"));
        lines.follow(child.stderr.take().expect("stderr"));
        let line = lines.wait_for("the router line", Duration::from_secs(20), |l| {
            l.contains(": router tcp/") || l.starts_with("error: ")
        });
        assert!(
            !line.starts_with("error: "),
            "the launcher refused the graph: {line}"
        );
        let endpoint = line
            .split("router ")
            .nth(1)
            .and_then(|s| s.split(',').next())
            .expect("router endpoint")
            .to_string();
        Launch {
            child,
            namespace: namespace.to_string(),
            endpoint,
            lines,
        }
    }

    /// Connection flags for a tool or a test's own bus to join this graph.
    pub fn connect_flags(&self) -> Vec<String> {
        vec![
            "--namespace".into(),
            self.namespace.clone(),
            "--connect".into(),
            self.endpoint.clone(),
        ]
    }

    pub fn connect_args(&self) -> interfaces::ConnectArgs {
        interfaces::ConnectArgs::to_router(&self.endpoint, &self.namespace)
    }

    /// Send SIGTERM to the launcher.
    pub fn sigterm(&self) {
        signal(self.child.id(), "TERM");
    }

    /// Wait for the launcher to exit, at most `timeout`.
    pub fn wait_exit(&mut self, timeout: Duration) -> ExitStatus {
        wait_child(&mut self.child, timeout).unwrap_or_else(|| {
            panic!(
                "launcher still running after {timeout:?}; output:\n{}",
                self.lines.all().join("\n")
            )
        })
    }

    /// Run `robocog <args...>` against this graph (connection flags appended).
    pub fn robocog(&self, args: &[&str], timeout: Duration) -> Output {
        let mut all: Vec<String> = args.iter().map(|s| s.to_string()).collect();
        all.extend(self.connect_flags());
        run(&bin("robocog"), &all, timeout)
    }
}

impl Drop for Launch {
    fn drop(&mut self) {
        if self.child.try_wait().ok().flatten().is_none() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// Send a signal by name (`TERM`, `KILL`) with kill(1).
pub fn signal(pid: u32, sig: &str) {
    let _ = Command::new("kill")
        .arg(format!("-{sig}"))
        .arg(pid.to_string())
        .status();
}

/// The fields of a `/proc/.../stat` line after the command's name in parentheses (which may
/// hold spaces and parentheses): the first is field 3, the state.
pub fn stat_fields(stat: &str) -> Vec<&str> {
    stat.rsplit(')')
        .next()
        .unwrap_or("")
        .split_whitespace()
        .collect()
}

/// Whether process `pid` exists (and is not a zombie).
pub fn alive(pid: u32) -> bool {
    match std::fs::read_to_string(format!("/proc/{pid}/stat")) {
        Ok(stat) => stat_fields(&stat).first().is_some_and(|s| *s != "Z"),
        Err(_) => false,
    }
}

/// Wait for a child to exit, at most `timeout`.
pub fn wait_child(child: &mut Child, timeout: Duration) -> Option<ExitStatus> {
    let deadline = Instant::now() + timeout;
    loop {
        if let Ok(Some(s)) = child.try_wait() {
            return Some(s);
        }
        if Instant::now() >= deadline {
            return None;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Run a command to completion with a time-out (killed and reported when it runs over).
pub fn run(program: &Path, args: &[String], timeout: Duration) -> Output {
    run_in(None, program, args, timeout)
}

/// [`run`] in the working folder `dir` (else the test's).
pub fn run_in(dir: Option<&Path>, program: &Path, args: &[String], timeout: Duration) -> Output {
    let mut command = Command::new(program);
    if let Some(dir) = dir {
        command.current_dir(dir);
    }
    let mut child = command
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot run {}: {e}", program.display()));
    let out = Lines::default();
    let err = Lines::default();
    out.follow(child.stdout.take().expect("stdout"));
    err.follow(child.stderr.take().expect("stderr"));
    let status = match wait_child(&mut child, timeout) {
        Some(s) => s,
        None => {
            let _ = child.kill();
            panic!(
                "{} {args:?} ran over {timeout:?}\nstdout:\n{}\nstderr:\n{}",
                program.display(),
                out.all().join("\n"),
                err.all().join("\n")
            );
        }
    };
    std::thread::sleep(Duration::from_millis(50));
    Output {
        status,
        stdout: (out.all().join("\n") + "\n").into_bytes(),
        stderr: (err.all().join("\n") + "\n").into_bytes(),
    }
}

/// A UDP port free on loopback now (for a simulated field's or a bridge's sockets).
pub fn free_udp_port() -> u16 {
    std::net::UdpSocket::bind("127.0.0.1:0")
        .and_then(|s| s.local_addr())
        .map(|a| a.port())
        .expect("a free UDP port on loopback")
}

/// A TCP port free on loopback now.
pub fn free_tcp_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|s| s.local_addr())
        .map(|a| a.port())
        .expect("a free TCP port on loopback")
}

/// Wait until `f` returns `Some`, polling, at most `timeout`.
pub fn eventually<T>(what: &str, timeout: Duration, mut f: impl FnMut() -> Option<T>) -> T {
    let deadline = Instant::now() + timeout;
    loop {
        if let Some(v) = f() {
            return v;
        }
        assert!(
            Instant::now() < deadline,
            "timed out after {timeout:?} waiting for {what}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The pid in a launcher's or an agent's line `started <name> (pid N): ...`.
pub fn started_pid(line: &str) -> Option<u32> {
    line.split("(pid ").nth(1)?.split(')').next()?.parse().ok()
}

/// The pid of live component `name`, from `robocog component list --json`.
pub fn component_pid(launch: &Launch, name: &str) -> Option<u32> {
    let out = launch.robocog(&["component", "list", "--json"], Duration::from_secs(15));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).ok()?;
    v.as_array()?
        .iter()
        .find(|c| c["name"] == name)
        .and_then(|c| c["pid"].as_u64())
        .map(|p| p as u32)
}

/// Start `robocog <args> <connection flags>` in the background, stderr into `log`.
pub fn start_tool(launch: &Launch, ns: &str, args: &[&str], log: &Path) -> Child {
    Command::new(bin("robocog"))
        .args(args)
        .args(["--namespace", ns, "--connect", &launch.endpoint])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(log).unwrap())
        .spawn()
        .unwrap()
}

/// `robocog record --output file` on `launch`'s namespace `ns`, its log in `log`, once it says it
/// records (within `timeout`).
pub fn start_recorder(
    launch: &Launch,
    ns: &str,
    file: &Path,
    log: &Path,
    timeout: Duration,
) -> Child {
    let rec = start_tool(
        launch,
        ns,
        &["record", "--output", &file.display().to_string()],
        log,
    );
    log_wait(log, "the recorder", timeout, |l| {
        l.starts_with("recording namespace")
    });
    rec
}

/// Wait until a line of the file `log` satisfies `pred`.
pub fn log_wait(log: &Path, what: &str, timeout: Duration, pred: impl Fn(&str) -> bool) -> String {
    let deadline = Instant::now() + timeout;
    loop {
        let text = std::fs::read_to_string(log).unwrap_or_default();
        if let Some(l) = text.lines().find(|l| pred(l)) {
            return l.to_string();
        }
        assert!(
            Instant::now() < deadline,
            "timed out after {timeout:?} waiting for {what}; log:\n{text}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// SIGTERM to a tool started with [`start_tool`], and its exit status (it must exit within 20 s).
pub fn sigterm_and_wait(child: &mut Child, log: &Path) -> ExitStatus {
    signal(child.id(), "TERM");
    wait_child(child, Duration::from_secs(20)).unwrap_or_else(|| {
        let _ = child.kill();
        panic!(
            "the tool ignored SIGTERM; log:\n{}",
            std::fs::read_to_string(log).unwrap_or_default()
        )
    })
}

/// A recorded message, as the mcap crate reads it.
pub struct Rec {
    pub topic: String,
    pub type_name: String,
    pub log_time: u64,
    pub publish_time: u64,
    pub sequence: u32,
    pub data: Vec<u8>,
}

/// A finished recording: its summary, every message in file order, and the recorder's
/// `robocog.record` metadata (namespace, drops per topic).
pub fn read_recording(path: &Path) -> (mcap::Summary, Vec<Rec>, BTreeMap<String, String>) {
    let bytes = std::fs::read(path).unwrap();
    let summary = mcap::Summary::read(&bytes)
        .unwrap()
        .expect("a finished recording has a summary");
    let msgs = mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            Rec {
                topic: m.channel.topic.clone(),
                // The robocog type, as replay reads it (the schema is named by the ROS 2 type).
                type_name: m
                    .channel
                    .metadata
                    .get("robocog.type")
                    .cloned()
                    .or_else(|| m.channel.schema.as_ref().map(|s| s.name.clone()))
                    .unwrap_or_default(),
                log_time: m.log_time,
                publish_time: m.publish_time,
                sequence: m.sequence,
                data: m.data.into_owned(),
            }
        })
        .collect();
    let mut meta = BTreeMap::new();
    for idx in &summary.metadata_indexes {
        let m = mcap::read::metadata(&bytes, idx).unwrap();
        if m.name == "robocog.record" {
            meta = m.metadata;
        }
    }
    (summary, msgs, meta)
}

/// A PulseAudio sound server of one test, standing for a room with a microphone in it: a null
/// sink `room` (what is played into the room) and a virtual source `mic` on the room's monitor
/// (what a microphone in the room hears). It listens on an anonymous unix socket in a fresh
/// folder ([`SoundServer::address`], libpulse's server string) and is stopped when dropped.
/// Nothing of it leaves the test's scratch folder: no other client or test can reach it.
/// As root it runs in system mode (it drops to the `pulse` user that Debian's package makes).
pub struct SoundServer {
    child: Child,
    dir: PathBuf,
    /// The server string to give clients (`unix:<folder>/native`).
    pub address: String,
    /// What the server logged.
    pub log: PathBuf,
}

/// What [`SoundServer::start_room`] adds to the room: the robot's loudspeaker and the person's
/// mouth as sinks of their own, the left and the right channel of a stereo `tap` that a test
/// records to measure one against the other on one clock; the tap is heard in the room (one
/// loop-back into `room`, 20 ms of air).
const ROOM_WITH_SPEAKER: &str = "\
    load-module module-null-sink sink_name=tap rate=48000 channels=2\n\
    load-module module-remap-sink sink_name=speaker master=tap channels=1 channel_map=mono \
        master_channel_map=front-left remix=no\n\
    load-module module-remap-sink sink_name=person master=tap channels=1 channel_map=mono \
        master_channel_map=front-right remix=no\n\
    load-module module-loopback source=tap.monitor sink=room latency_msec=20\n";

impl SoundServer {
    /// Start one for the test `tag`, waiting (10 s at most) until it answers.
    pub fn start(tag: &str) -> SoundServer {
        Self::start_with(tag, "")
    }

    /// A room where the robot's voice and the person's come from sinks of their own (`speaker`
    /// and `person`), so that an echo canceller can take the robot's voice out of what the
    /// microphone (`room.monitor`) hears, with `tap.monitor` hearing both apart (left: the
    /// loudspeaker, right: the person). The two sinks are the two channels of the tap itself,
    /// heard in the room through one loop-back: the tap hears them on one clock, and the
    /// microphone hears them with one delay (two loop-backs' latencies drift apart by tens of
    /// milliseconds).
    pub fn start_room(tag: &str) -> SoundServer {
        Self::start_with(tag, ROOM_WITH_SPEAKER)
    }

    /// A room with a microphone array: besides the usual devices, a null sink `array` of
    /// `channels` channels at 16 kHz mapped `aux0`, `aux1`, ... as a USB array shows up; its
    /// monitor (`array.monitor`) is the array's source, heard as played into it.
    pub fn start_array(tag: &str, channels: usize) -> SoundServer {
        Self::start_with(
            tag,
            &format!(
                "load-module module-null-sink sink_name=array rate=16000 channels={channels} \
                 channel_map={}\n",
                Self::aux_map(channels)
            ),
        )
    }

    /// The channel map `aux0,aux1,...` of `channels` channels.
    pub fn aux_map(channels: usize) -> String {
        (0..channels)
            .map(|k| format!("aux{k}"))
            .collect::<Vec<_>>()
            .join(",")
    }

    /// Play `samples` (`channels` interleaved, 16 kHz) into `sink` with the channel map `map`,
    /// returning once all of it was played (`timeout` at most).
    pub fn play(&self, sink: &str, channels: usize, map: &str, samples: &[i16], timeout: Duration) {
        let file = self.dir.join(format!("play-{}.raw", std::process::id()));
        let bytes: Vec<u8> = samples.iter().flat_map(|s| s.to_le_bytes()).collect();
        std::fs::write(&file, bytes).expect("the sound to play");
        let out = run(
            Path::new("pacat"),
            &[
                "--server".into(),
                self.address.clone(),
                "--device".into(),
                sink.into(),
                "--raw".into(),
                "--format=s16le".into(),
                "--rate=16000".into(),
                format!("--channels={channels}"),
                format!("--channel-map={map}"),
                file.display().to_string(),
            ],
            timeout,
        );
        assert!(
            out.status.success(),
            "pacat: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }

    fn start_with(tag: &str, more: &str) -> SoundServer {
        let dir = scratch(&unique_namespace(&format!("sound-{tag}"))).join("pulse");
        std::fs::create_dir_all(&dir).expect("sound server dir");
        // The server drops to its own user: it must be able to make its socket here.
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o777))
            .expect("sound server dir mode");
        let socket = dir.join("native");
        let script = dir.join("room.pa");
        std::fs::write(
            &script,
            format!(
                "load-module module-native-protocol-unix socket={} auth-anonymous=1\n\
                 load-module module-null-sink sink_name=room rate=48000 channels=2\n\
                 load-module module-virtual-source source_name=mic master=room.monitor\n{more}",
                socket.display()
            ),
        )
        .expect("sound server script");
        let log = dir.join("server.log");
        let server = SoundServer {
            child: Self::spawn(&dir, &script, &log),
            address: format!("unix:{}", socket.display()),
            dir,
            log,
        };
        server.wait_until_it_answers();
        server
    }

    /// Kill the server (as a crash would) and start it again on the same socket with the same
    /// devices, waiting (10 s at most) until it answers; its log goes on in the same file.
    pub fn restart(&mut self) {
        self.kill();
        let script = self.dir.join("room.pa");
        self.child = Self::spawn(&self.dir, &script, &self.log);
        self.wait_until_it_answers();
    }

    /// Kill the server, as a crash would (its socket file is removed, as it would not be).
    pub fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_file(self.dir.join("native"));
    }

    fn wait_until_it_answers(&self) {
        eventually("the sound server answers", Duration::from_secs(10), || {
            self.pactl(&["list", "short", "sources"])
                .status
                .success()
                .then_some(())
        });
    }

    fn spawn(dir: &Path, script: &Path, log: &Path) -> Child {
        use std::os::unix::fs::MetadataExt;
        let root = std::fs::metadata("/proc/self").is_ok_and(|m| m.uid() == 0);
        let mut cmd = Command::new("pulseaudio");
        if root {
            cmd.arg("--system");
        }
        cmd.args([
            "--daemonize=no",
            "--use-pid-file=no",
            "--disallow-exit",
            "--exit-idle-time=-1",
            "--log-target=stderr",
            "-n",
            "-F",
        ])
        .arg(script)
        // Its runtime folder (made by the server itself, which insists on owning it).
        .env("PULSE_RUNTIME_PATH", dir.join("runtime"))
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(
            std::fs::OpenOptions::new()
                .create(true)
                .append(true)
                .open(log)
                .expect("sound server log"),
        );
        cmd.spawn()
            .expect("start pulseaudio (Debian's pulseaudio package; scripts/test installs it)")
    }

    /// Run `pactl` against this server.
    pub fn pactl(&self, args: &[&str]) -> Output {
        let mut all = vec!["--server".to_string(), self.address.clone()];
        all.extend(args.iter().map(|a| a.to_string()));
        run(Path::new("pactl"), &all, Duration::from_secs(10))
    }

    /// Record `source` as 16 kHz mono s16le into `file` until the returned child is stopped.
    pub fn record(&self, source: &str, file: &Path) -> Child {
        self.record_channels(source, file, 1)
    }

    /// Record `source` as 16 kHz s16le with `channels` interleaved into `file`.
    pub fn record_channels(&self, source: &str, file: &Path, channels: u8) -> Child {
        Command::new("parec")
            .args(["--server", &self.address, "--device", source])
            .args(["--raw", "--format=s16le", "--rate=16000"])
            .arg(format!("--channels={channels}"))
            .arg("--latency-msec=20")
            .stdin(Stdio::null())
            .stdout(std::fs::File::create(file).expect("recording file"))
            .stderr(Stdio::null())
            .spawn()
            .expect("start parec (Debian's pulseaudio-utils)")
    }
}

impl Drop for SoundServer {
    fn drop(&mut self) {
        // The folder (with the server's log) stays for a failed test to be read; the scratch
        // folders are pruned by later runs.
        self.kill();
    }
}

/// The first diagnostics on `diagnostics` that `pick` takes (10 s at most, else the test fails
/// with the last one seen).
pub async fn diagnostics_until(
    diagnostics: &interfaces::Subscriber<interfaces::msg::diag::Diagnostics>,
    pick: impl Fn(&interfaces::msg::diag::Diagnostics) -> bool,
) -> interfaces::msg::diag::Diagnostics {
    let mut last = None;
    let found = tokio::time::timeout(Duration::from_secs(10), async {
        loop {
            let d = diagnostics.recv().await.unwrap();
            if pick(&d) {
                return d;
            }
            last = Some(d);
        }
    })
    .await;
    found.unwrap_or_else(|_| panic!("no such diagnostics within 10 s; the last: {last:?}"))
}

/// Everything received on a topic, drained in the background (subscriber queues are bounded).
pub struct Log<T>(pub Arc<Mutex<Vec<T>>>);

impl<T: interfaces::Message + Clone + Send + std::fmt::Debug + 'static> Log<T> {
    pub async fn follow(bus: &interfaces::Bus, topic: &interfaces::Topic<T>) -> Log<T> {
        let sub: interfaces::Subscriber<T> = bus.subscriber(topic).await.unwrap();
        let v = Arc::new(Mutex::new(Vec::new()));
        let w = v.clone();
        tokio::spawn(async move {
            while let Ok(m) = sub.recv().await {
                w.lock().unwrap().push(m);
            }
        });
        Log(v)
    }
    pub fn all(&self) -> Vec<T> {
        self.0.lock().unwrap().clone()
    }
    #[allow(clippy::len_without_is_empty)]
    pub fn len(&self) -> usize {
        self.0.lock().unwrap().len()
    }
    pub fn last(&self) -> Option<T> {
        self.0.lock().unwrap().last().cloned()
    }
    /// The first message from index `from` on that satisfies `pred`, waiting at most `timeout`.
    pub async fn wait_from(
        &self,
        what: &str,
        from: usize,
        timeout: Duration,
        pred: impl Fn(&T) -> bool,
    ) -> T {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(m) = self.0.lock().unwrap().iter().skip(from).find(|m| pred(m)) {
                return m.clone();
            }
            if Instant::now() >= deadline {
                let tail = {
                    let v = self.0.lock().unwrap();
                    let tail: Vec<_> = v.iter().skip(v.len().saturating_sub(12)).collect();
                    format!("{tail:#?}")
                };
                panic!(
                    "timed out after {timeout:?} waiting for {what}; the last messages:\n{tail}"
                );
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    }
}
