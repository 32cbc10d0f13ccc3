#![allow(clippy::unwrap_used, clippy::expect_used)] // tests: a panic is how a test fails
//! One graph over several machines: network namespaces joined by veth pairs stand for the
//! machines (root needed, as in CI), each with its own network stack, loopback and ports.
//! `robocog launch` runs on one machine, `robocog agent` on each other; the routers join over
//! mutual TLS with access control.
#![expect(
    clippy::disallowed_methods,
    reason = "process tests wait on real processes, with a time-out on every wait"
)]

use robocog_tests::netns::{Net, Proc};
use robocog_tests::{bin, run, scratch, unique_namespace};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

const PORT: u16 = 7450;

/// A graph whose machines are `names`, machine `i` at `net`'s address `i`, with `components`.
fn write_graph(dir: &Path, net_ips: &[String], names: &[&str], components: &str) -> PathBuf {
    let mut text = String::from("[graph]\nname = \"split\"\ncerts = \"certs\"\n\n");
    for (name, ip) in names.iter().zip(net_ips) {
        text.push_str(&format!(
            "[machines.{name}]\nrouter = \"tls/{ip}:{PORT}\"\n\n"
        ));
    }
    text.push_str(components);
    let p = dir.join("graph.toml");
    std::fs::write(&p, text).unwrap();
    p
}

fn certs(manifest: &Path) {
    let out = run(
        &bin("robocog"),
        &["certs".into(), manifest.display().to_string()],
        Duration::from_secs(30),
    );
    assert!(
        out.status.success(),
        "robocog certs: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn agent(net: &Net, i: usize, machine: &str, manifest: &Path, ns: &str) -> Proc {
    agent_with(net, i, machine, manifest, ns, &[])
}

fn agent_with(
    net: &Net,
    i: usize,
    machine: &str,
    manifest: &Path,
    ns: &str,
    extra: &[&str],
) -> Proc {
    let mut args: Vec<String> = vec![
        "agent".into(),
        manifest.display().to_string(),
        "--machine".into(),
        machine.into(),
        "--namespace".into(),
        ns.into(),
        "--router".into(),
        "tcp/127.0.0.1:0".into(),
        "--state-root".into(),
        scratch(ns)
            .join(format!("state-{machine}"))
            .display()
            .to_string(),
    ];
    args.extend(extra.iter().map(|s| s.to_string()));
    let p = net.spawn(i, &bin("robocog"), &args);
    p.lines
        .wait_for("the agent ready", Duration::from_secs(20), |l| {
            l.contains("ready: waiting for a launch") || l.starts_with("error")
        });
    p
}

fn launch(net: &Net, i: usize, machine: &str, manifest: &Path, ns: &str, extra: &[&str]) -> Proc {
    let mut args: Vec<String> = [
        "launch",
        &manifest.display().to_string(),
        "--machine",
        machine,
        "--namespace",
        ns,
        "--router",
        "tcp/127.0.0.1:0",
        "--color",
        "never",
        "--state-root",
        &scratch(ns)
            .join(format!("state-{machine}"))
            .display()
            .to_string(),
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    args.extend(extra.iter().map(|s| s.to_string()));
    net.spawn(i, &bin("robocog"), &args)
}

/// The highest "hello N" the listener printed.
fn last_hello(p: &Proc) -> u64 {
    p.lines
        .all()
        .iter()
        .filter(|l| l.contains("robot/listener |"))
        .filter_map(|l| l.split("received: hello ").nth(1))
        .filter_map(|s| s.split_whitespace().next()?.parse().ok())
        .max()
        .unwrap_or(0)
}

const TALK: &str = r#"
[[component]]
name = "talker"
binary = "fixture_node"
args = ["--role", "talker", "--rate", "10"]
machine = "speech"

[[component]]
name = "listener"
binary = "fixture_node"
args = ["--role", "listener"]
depends_on = ["talker"]
machine = "robot"
"#;

#[test]
fn a_graph_over_two_machines_starts_across_them_and_notices_one_that_drops_off() {
    let ns = unique_namespace("machines");
    let net = Net::new(2);
    let dir = scratch(&ns);
    let manifest = write_graph(&dir, &[net.ip(0), net.ip(1)], &["robot", "speech"], TALK);
    certs(&manifest);
    let speech = agent(&net, 1, "speech", &manifest, &ns);
    let mut robot = launch(&net, 0, "robot", &manifest, &ns, &[]);

    // The talker runs on the other machine, started there by its agent, its lines here with
    // their machine; the listener here hears it through the two routers.
    robot.lines.wait_for(
        "the listener hearing the talker",
        Duration::from_secs(30),
        |l| l.contains("robot/listener | received: hello 3"),
    );
    assert!(robot.lines.count(|l| l.starts_with(" speech/talker |")) > 0);
    assert!(speech.lines.count(|l| l.contains("started talker (pid")) == 1);

    // The speech machine's cable is pulled: noticed within the links' lease, and said.
    net.link(1, false);
    let pulled = Instant::now();
    robot.lines.wait_for(
        "the speech machine out of reach",
        Duration::from_secs(15),
        |l| l.contains("machine speech is out of reach") && l.contains("talker"),
    );
    let noticed = pulled.elapsed();
    assert!(
        noticed < Duration::from_secs(8),
        "noticed after {noticed:?}"
    );
    let before = last_hello(&robot);

    // Back: the routers rejoin by themselves, the talker ran on, and is heard again.
    net.link(1, true);
    let back = Instant::now() + Duration::from_secs(30);
    while robot
        .lines
        .count(|l| l.contains("machine speech: talker ran on while it was away"))
        == 0
    {
        assert!(
            Instant::now() < back,
            "the speech machine not back 30 s after its cable; the robot:\n{}\n\nthe speech machine:\n{}",
            robot.lines.all().join("\n"),
            speech.lines.all().join("\n")
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    let deadline = Instant::now() + Duration::from_secs(15);
    while last_hello(&robot) <= before + 5 {
        assert!(
            Instant::now() < deadline,
            "the listener did not hear the talker again (last hello {} before, {} now):\n{}",
            before,
            last_hello(&robot),
            robot.lines.all().join("\n")
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    assert_eq!(
        robot.lines.count(|l| l.contains("restart")),
        0,
        "nothing was restarted:\n{}",
        robot.lines.all().join("\n")
    );
    assert_eq!(speech.lines.count(|l| l.contains("started talker")), 1);

    // An agent starts only what its own manifest places on its machine, as it has it: a request
    // for anything else, from anywhere on the bus, is refused and changes nothing.
    let router = robot
        .lines
        .wait_for("the robot's router", Duration::from_secs(1), |l| {
            l.contains(": router tcp/")
        });
    let endpoint = router
        .split("router ")
        .nth(1)
        .and_then(|s| s.split(',').next())
        .expect("an endpoint")
        .to_string();
    let marker = dir.join("should-not-exist");
    for (component, binary, args) in [
        (
            "evil",
            "sh",
            vec!["-c".to_string(), format!("touch {}", marker.display())],
        ),
        (
            "talker",
            "sh",
            vec!["-c".to_string(), format!("touch {}", marker.display())],
        ),
    ] {
        let request = serde_json::json!({
            "header": {"stamp_ns": 0, "seq": 0, "frame_id": ""},
            "launch_id": "someone-else", "graph": "split", "action": "Start",
            "component": component, "generation": 1, "binary": binary, "dir": "/",
            "args": args, "env": [], "stop_timeout_ms": 0,
        });
        let mut call = net.spawn(
            0,
            &bin("robocog"),
            &[
                "service".into(),
                "call".into(),
                "agent/speech/control".into(),
                request.to_string(),
                "--namespace".into(),
                ns.clone(),
                "--connect".into(),
                endpoint.clone(),
            ],
        );
        let status = call.wait_exit(Duration::from_secs(20));
        let said = call.lines.all().join("\n");
        assert!(!status.success(), "{said}");
        assert!(
            said.contains("places no component \"evil\"")
                || said.contains("the launcher's manifest and this agent's differ for talker"),
            "{said}"
        );
    }
    assert!(!marker.exists());
    assert_eq!(speech.lines.count(|l| l.contains("started talker")), 1);
    assert_eq!(speech.lines.count(|l| l.contains("a new launch")), 0);

    // A component that crashes on the other machine is restarted there by its policy.
    let line = speech
        .lines
        .wait_for("the talker's pid", Duration::from_secs(1), |l| {
            l.contains("started talker (pid")
        });
    let pid = robocog_tests::started_pid(&line).expect("a pid");
    robocog_tests::signal(pid, "KILL");
    robot
        .lines
        .wait_for("the talker restarted", Duration::from_secs(10), |l| {
            l.contains("talker stopped (killed by signal 9") && l.contains("restart 1/")
        });
    speech
        .lines
        .wait_until("a second talker", Duration::from_secs(10), |lines| {
            lines
                .iter()
                .filter(|l| l.contains("started talker (pid"))
                .count()
                == 2
        });
    robot
        .lines
        .wait_for("the talker up again", Duration::from_secs(10), |l| {
            l.contains("talker is up") && !l.contains(&format!("pid {pid},"))
        });

    // The other machine's router dies (SIGKILL): its agent starts it again on the same
    // endpoints, the talker rejoins it and the two routers link again; the listener hears the
    // talker on, and nothing is restarted for it.
    let router_line =
        speech
            .lines
            .wait_for("the speech machine's router", Duration::from_secs(1), |l| {
                l.contains("started router (pid ")
            });
    let router_pid = robocog_tests::started_pid(&router_line).expect("the router's pid");
    let before = last_hello(&robot);
    robocog_tests::signal(router_pid, "KILL");
    speech.lines.wait_until(
        "the router started again",
        Duration::from_secs(20),
        |lines| {
            lines
                .iter()
                .filter(|l| l.contains("started router (pid "))
                .count()
                == 2
        },
    );
    let deadline = Instant::now() + Duration::from_secs(30);
    while last_hello(&robot) <= before + 5 {
        assert!(
            Instant::now() < deadline,
            "the listener did not hear the talker after the router's restart (last hello {} \
             before, {} now):\n{}\n\nspeech:\n{}",
            before,
            last_hello(&robot),
            robot.lines.all().join("\n"),
            speech.lines.all().join("\n")
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    assert_eq!(speech.lines.count(|l| l.contains("started talker")), 2);
    assert!(robocog_tests::alive(speech.child.id()), "the agent went on");

    // Stopping the launch stops the other machine's components too; the agent stays for the
    // next launch.
    robot.sigterm();
    let status = robot.wait_exit(Duration::from_secs(30));
    assert!(status.success(), "{}", robot.lines.all().join("\n"));
    speech.lines.wait_for(
        "the talker stopped by its agent",
        Duration::from_secs(5),
        |l| l.contains("talker exited"),
    );
    assert!(speech.child.id() > 0 && robocog_tests::alive(speech.child.id()));
}

#[test]
fn a_machine_without_the_graphs_certificate_cannot_publish_into_it() {
    let ns = unique_namespace("intruder");
    let net = Net::new(3);
    let dir = scratch(&ns);
    // The graph: the robot (listening) and the speech machine. A third host, the laptop, gets a
    // certificate from the same CA but is no machine of the graph.
    let listen_only = r#"
[[component]]
name = "listener"
binary = "fixture_node"
args = ["--role", "listener"]
machine = "robot"
external_inputs = ["chatter"]
"#;
    let manifest = write_graph(
        &dir,
        &[net.ip(0), net.ip(1)],
        &["robot", "speech"],
        listen_only,
    );
    certs(&manifest);
    let other = dir.join("other");
    std::fs::create_dir_all(&other).unwrap();
    let with_laptop = other.join("graph.toml");
    std::fs::write(
        &with_laptop,
        std::fs::read_to_string(&manifest)
            .unwrap()
            .replace("certs = \"certs\"", "certs = \"../certs\"")
            + &format!(
                "\n[machines.laptop]\nrouter = \"tls/{}:{PORT}\"\n",
                net.ip(2)
            ),
    )
    .unwrap();
    certs(&with_laptop);
    // And a host with a CA of its own.
    let foreign = dir.join("foreign");
    std::fs::create_dir_all(&foreign).unwrap();
    let foreign_manifest = foreign.join("graph.toml");
    std::fs::write(
        &foreign_manifest,
        std::fs::read_to_string(&manifest).unwrap(),
    )
    .unwrap();
    certs(&foreign_manifest);

    let robot = launch(&net, 0, "robot", &manifest, &ns, &[]);
    robot
        .lines
        .wait_for("the listener up", Duration::from_secs(20), |l| {
            l.contains("listener is up")
        });

    // Publish from a host with a client configuration using `certs`'s files of `machine`.
    let publish = |host: usize, certs: &Path, machine: &str, text: &str, tls: bool| {
        let config = dir.join(format!("client-{text}.json5"));
        let tls_conf = serde_json::json!({
            "root_ca_certificate": certs.join("ca.pem"),
            "connect_certificate": certs.join(format!("{machine}.pem")),
            "connect_private_key": certs.join(format!("{machine}.key")),
            "enable_mtls": true,
        });
        std::fs::write(
            &config,
            serde_json::json!({
                "scouting": {"multicast": {"enabled": false}},
                "transport": {"link": {"tls": tls_conf}},
            })
            .to_string(),
        )
        .unwrap();
        let proto = if tls { "tls" } else { "tcp" };
        let mut p = net.spawn(
            host,
            &bin("robocog"),
            &[
                "topic".into(),
                "pub".into(),
                "chatter".into(),
                format!(r#"{{"text": "{text}"}}"#),
                "--type".into(),
                "robocog.Text".into(),
                "--count".into(),
                "5".into(),
                "--rate".into(),
                "10".into(),
                "--namespace".into(),
                ns.clone(),
                "--connect".into(),
                format!("{proto}/{}:{PORT}", net.ip(0)),
                "--config".into(),
                config.display().to_string(),
            ],
        );
        let status = p.wait_exit(Duration::from_secs(30));
        (status, p.lines.all().join("\n"))
    };

    // The graph's own speech machine can (the control: the path works).
    let (status, out) = publish(1, &dir.join("certs"), "speech", "from-speech", true);
    assert!(status.success(), "{out}");
    robot.lines.wait_for(
        "the speech machine's message",
        Duration::from_secs(10),
        |l| l.contains("received: from-speech"),
    );

    // A CA of its own: the TLS handshake fails, nothing gets in.
    let (status, out) = publish(2, &foreign.join("certs"), "speech", "from-foreign", true);
    assert!(
        !status.success(),
        "a foreign certificate joined the bus:\n{out}"
    );
    // No TLS at all.
    let (status, out) = publish(2, &foreign.join("certs"), "speech", "from-plain", false);
    assert!(!status.success(), "plain TCP joined the bus:\n{out}");
    // The right CA but no machine of the graph: the link opens (the tool runs to its end), and
    // access control drops everything it sends.
    let (status, out) = publish(2, &dir.join("certs"), "laptop", "from-laptop", true);
    assert!(
        status.success(),
        "the laptop's link did not even open:\n{out}"
    );

    // Give anything that got through time to arrive, then look.
    std::thread::sleep(Duration::from_secs(2));
    let heard = robot.lines.all().join("\n");
    for text in ["from-foreign", "from-plain", "from-laptop"] {
        assert!(!heard.contains(text), "{text} got into the graph:\n{heard}");
    }
}

#[test]
fn a_launch_whose_other_machine_has_no_agent_says_so_and_fails() {
    // Two "machines" on loopback (plain TCP stays on the host: no certificates needed).
    let ns = unique_namespace("noagent");
    let dir = scratch(&ns);
    let (a, b) = (
        robocog_tests::free_tcp_port(),
        robocog_tests::free_tcp_port(),
    );
    let manifest = dir.join("graph.toml");
    std::fs::write(
        &manifest,
        format!(
            "[graph]\nname = \"noagent\"\n[machines.robot]\nrouter = \"tcp/127.0.0.1:{a}\"\n[machines.speech]\nrouter = \"tcp/127.0.0.1:{b}\"\n{TALK}"
        ),
    )
    .unwrap();
    let started = Instant::now();
    let out = run(
        &bin("robocog"),
        &[
            "launch".into(),
            manifest.display().to_string(),
            "--machine".into(),
            "robot".into(),
            "--namespace".into(),
            ns.clone(),
            "--router".into(),
            "tcp/127.0.0.1:0".into(),
            "--machine-timeout-s".into(),
            "2".into(),
            "--state-root".into(),
            dir.join("state").display().to_string(),
        ],
        Duration::from_secs(30),
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("no agent on machine speech within 2 s") && err.contains("robocog agent"),
        "{err}"
    );
    assert!(started.elapsed() < Duration::from_secs(15));
    // Without --machine, the launcher asks which machine it is on.
    let out = run(
        &bin("robocog"),
        &["launch".into(), manifest.display().to_string()],
        Duration::from_secs(30),
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("--machine") && err.contains("robot, speech"),
        "{err}"
    );
}

/// Loki's game over three machines as the seed split it, each link 20 ms late and losing 1 % of
/// its packets, and the speech machine's cable pulled in the middle of the game: the robot says
/// it cannot hear, the speech machine's components run on, and once the cable is back the game
/// goes on to its end without the person repeating herself.
#[test]
fn the_touch_game_over_three_machines_survives_a_slow_lossy_network_and_a_lost_speech_machine() {
    let ns = unique_namespace("split");
    let mut net = Net::new(3);
    let dir = scratch(&ns);
    let manifest =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../launch/touch_the_ball_split.toml");
    let sets: Vec<String> = [
        format!("robot_ip={}", net.ip(0)),
        format!("speech_ip={}", net.ip(1)),
        format!("operator_ip={}", net.ip(2)),
        format!("certs={}", dir.join("certs").display()),
        "scenario=machine_away".into(),
        "panel_http=127.0.0.1:0".into(),
    ]
    .into_iter()
    .flat_map(|s| ["--set".to_string(), s])
    .collect();
    let mut args = vec!["certs".to_string(), manifest.display().to_string()];
    args.extend(sets.iter().cloned());
    let out = run(&bin("robocog"), &args, Duration::from_secs(30));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for i in 0..3 {
        net.impair(i, 20, 10);
    }
    let agent_with_sets = |i: usize, machine: &str| {
        let mut a = vec![
            "agent".to_string(),
            manifest.display().to_string(),
            "--machine".into(),
            machine.into(),
            "--namespace".into(),
            ns.clone(),
            "--router".into(),
            "tcp/127.0.0.1:0".into(),
            "--state-root".into(),
            dir.join(format!("state-{machine}")).display().to_string(),
        ];
        a.extend(sets.iter().cloned());
        let p = net.spawn(i, &bin("robocog"), &a);
        p.lines
            .wait_for("the agent ready", Duration::from_secs(30), |l| {
                l.contains("ready: waiting for a launch") || l.starts_with("error")
            });
        p
    };
    let speech = agent_with_sets(1, "speech");
    let _operator = agent_with_sets(2, "operator");
    let sets_ref: Vec<&str> = sets.iter().map(String::as_str).collect();
    let mut robot = launch(&net, 0, "robot", &manifest, &ns, &sets_ref);

    // The person sees the robot look at the ball: the speech machine's cable is pulled.
    robot.lines.wait_for(
        "the robot looking at the ball",
        Duration::from_secs(180),
        |l| l.contains("person: sees gaze within"),
    );
    net.link(1, false);
    let pulled = Instant::now();
    robot.lines.wait_for(
        "the speech machine out of reach",
        Duration::from_secs(15),
        |l| l.contains("machine speech is out of reach"),
    );
    robot.lines.wait_for(
        "the robot saying it cannot hear",
        Duration::from_secs(15),
        |l| l.contains("robot/executive |") && l.contains("nothing brings the person's voice"),
    );
    let away = Duration::from_secs(12);
    std::thread::sleep(away.saturating_sub(pulled.elapsed()));
    net.link(1, true);
    robot.lines.wait_for(
        "the speech machine back, its components still running",
        Duration::from_secs(30),
        |l| {
            l.contains("machine speech:")
                && l.contains("dialogs")
                && l.contains("ran on while it was away")
        },
    );
    robot.lines.wait_for(
        "the robot saying it hears again",
        Duration::from_secs(20),
        |l| l.contains("robot/executive |") && l.contains("the voice is back"),
    );

    // The game goes on to its end: the person, on the speech machine, completes her scenario.
    let status = robot.wait_exit(Duration::from_secs(180));
    let out = robot.lines.all().join("\n");
    // The links between the machines went through the delay lines (the speech machine's twice:
    // before the cable was pulled and after).
    for i in 0..3 {
        assert!(net.relayed_to(i) >= 1, "no link to machine {i} was delayed");
    }
    assert!(status.success(), "the game did not complete:\n{out}");
    assert!(out.contains("speech/loki_world |"), "{out}");
    assert!(out.contains("loki_world completed"), "{out}");
    assert_eq!(
        robot.lines.count(|l| l.contains("says it again")),
        0,
        "the person had to repeat herself:\n{out}"
    );
    assert_eq!(
        speech.lines.count(|l| l.contains("started dialogs")),
        1,
        "the speech machine's components were restarted"
    );
}

#[test]
fn an_agent_stops_the_components_of_a_launcher_that_is_gone_for_good() {
    let ns = unique_namespace("orphans");
    let net = Net::new(2);
    let dir = scratch(&ns);
    let manifest = write_graph(&dir, &[net.ip(0), net.ip(1)], &["robot", "speech"], TALK);
    certs(&manifest);
    let speech = agent_with(
        &net,
        1,
        "speech",
        &manifest,
        &ns,
        &["--orphan-after-s", "2"],
    );
    let mut robot = launch(&net, 0, "robot", &manifest, &ns, &[]);
    robot
        .lines
        .wait_for("the listener hearing", Duration::from_secs(30), |l| {
            l.contains("received: hello 2")
        });
    // The launcher dies without a word: its local children die with it; the other machine's
    // run on for the grace, then their agent stops them.
    robocog_tests::signal(robot.child.id(), "KILL");
    robot.wait_exit(Duration::from_secs(10));
    speech.lines.wait_for(
        "the agent noticing the launcher gone",
        Duration::from_secs(10),
        |l| l.contains("the launcher is out of reach"),
    );
    speech.lines.wait_for(
        "the orphaned talker stopped",
        Duration::from_secs(15),
        |l| l.contains("the launcher has been gone 2 s: stopping its 1 component"),
    );
    speech
        .lines
        .wait_for("the talker exited", Duration::from_secs(10), |l| {
            l.contains("talker exited")
        });
    // And a new launch is served by the same agent.
    let robot = launch(&net, 0, "robot", &manifest, &ns, &[]);
    robot
        .lines
        .wait_for("a new launch hearing", Duration::from_secs(30), |l| {
            l.contains("received: hello 2")
        });
}
