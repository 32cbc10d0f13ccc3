#![allow(clippy::unwrap_used)]
//! The Nao link end to end: the bridge and the simulated field as separate processes on real
//! UDP (loopback), commands from the bus reaching the simulated robot, world models and the
//! game state coming back, bad datagrams counted, link loss reported.
#![expect(
    clippy::disallowed_methods,
    reason = "process tests wait on real processes, with a time-out on every wait"
)]

use interfaces::msg::nao::{FieldPoint, LinkChange, NaoBody, NaoCommand};
use interfaces::{Bus, topics};
use robocog_tests::*;
use std::time::Duration;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn commands_reach_the_simulated_robot_and_its_world_comes_back() {
    let ns = unique_namespace("nao");
    let manifest =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../launch/nao_field.toml");
    let (debug, gc, cmd) = (free_udp_port(), free_udp_port(), free_udp_port());
    let sets = [
        format!("debug_port={debug}"),
        format!("gc_port={gc}"),
        format!("command_port={cmd}"),
    ];
    let mut extra = Vec::new();
    for s in &sets {
        extra.push("--set");
        extra.push(s.as_str());
    }
    let launch = Launch::start(&manifest, &ns, &extra);
    launch
        .lines
        .wait_for("bridge up", Duration::from_secs(30), |l| {
            l.contains("nao_bridge is up")
        });
    let bus = Bus::open(&launch.connect_args(), "test-coach")
        .await
        .unwrap();
    let world = bus.subscriber(&topics::NAO_WORLD_MODEL).await.unwrap();
    let game = bus.subscriber(&topics::NAO_GAME_STATE).await.unwrap();
    let truth = bus.subscriber(&topics::SIM_FIELD_TRUTH).await.unwrap();
    let links = bus.subscriber(&topics::NAO_LINK).await.unwrap();
    let diag = bus.subscriber(&topics::DIAGNOSTICS).await.unwrap();
    // Event waits, generous for a machine that runs other work beside the suite (the field and
    // the bridge start together, and the first packets may be sent before the bridge listens).
    let t = Duration::from_secs(30);

    // Both robots' debug packets are fused into the team model.
    let deadline = tokio::time::Instant::now() + t;
    loop {
        let w = tokio::time::timeout_at(deadline, world.recv())
            .await
            .expect("world model")
            .unwrap();
        let numbers: Vec<u8> = w.robots.iter().map(|r| r.player_number).collect();
        if numbers.contains(&1) && numbers.contains(&2) {
            break;
        }
    }
    // The GameController's state, with our team found by number.
    let g = tokio::time::timeout(t, game.recv())
        .await
        .expect("game state")
        .unwrap();
    assert!(g.our_team_found);
    assert_eq!(g.our_team.team_number, 19);

    // Wait for PLAYING (the robot obeys only then), then send GoToPosition over the bus.
    let deadline = tokio::time::Instant::now() + Duration::from_secs(20);
    loop {
        let f = tokio::time::timeout_at(deadline, truth.recv())
            .await
            .expect("PLAYING")
            .unwrap();
        if f.game_state == 3 {
            break;
        }
    }
    let commands = bus.publisher(&topics::NAO_COMMAND).await.unwrap();
    tokio::time::sleep(Duration::from_millis(300)).await;
    let mut go = NaoCommand {
        body: NaoBody::GoToPosition,
        target: FieldPoint {
            x_mm: -1500.0,
            y_mm: 1000.0,
        },
        source: "test".into(),
        ..Default::default()
    };
    commands.publish(&mut go).await.unwrap();
    // The exact packet arrived at the robot, and the robot walks there.
    let deadline = tokio::time::Instant::now() + Duration::from_secs(30);
    let mut got_packet = false;
    loop {
        let f = tokio::time::timeout_at(deadline, truth.recv())
            .await
            .expect("the robot to arrive")
            .unwrap();
        if f.commands_received > 0 {
            assert_eq!(f.last_command, vec![1.0, 0.0, 0.0, -1500.0, 1000.0]);
            got_packet = true;
        }
        let d =
            ((f.controlled.x_mm + 1500.0).powi(2) + (f.controlled.y_mm - 1000.0).powi(2)).sqrt();
        if got_packet && d < 200.0 {
            break;
        }
    }

    // Garbage on the debug port: a wrong-size packet from the robot's address, and a packet
    // from an unknown address; both counted by reason, and the bridge carries on.
    let from_robot = std::net::UdpSocket::bind("127.0.0.2:0").unwrap();
    from_robot
        .send_to(&[1, 2, 3], ("127.0.0.1", debug))
        .unwrap();
    let stranger = std::net::UdpSocket::bind("127.0.0.9:0").unwrap();
    stranger.send_to(&[0u8; 356], ("127.0.0.1", debug)).unwrap();
    let deadline = tokio::time::Instant::now() + t;
    loop {
        let d = tokio::time::timeout_at(deadline, diag.recv())
            .await
            .expect("drop counters")
            .unwrap();
        if d.component == "nao_bridge"
            && d.get("drop/debug/wrong_size") >= 1
            && d.get("drop/debug/unknown_source") >= 1
        {
            break;
        }
    }
    tokio::time::timeout(t, world.recv())
        .await
        .expect("still publishing")
        .unwrap();

    // The field goes away: the bridge says the robot is not responding.
    let field = eventually("field pid", t, || component_pid(&launch, "spl_field"));
    signal(field, "STOP");
    let deadline = tokio::time::Instant::now() + t;
    loop {
        let e = tokio::time::timeout_at(deadline, links.recv())
            .await
            .expect("link loss")
            .unwrap();
        if e.change == LinkChange::RobotNotResponding && e.player_number == 2 {
            break;
        }
    }
    signal(field, "CONT");
    let deadline = tokio::time::Instant::now() + t;
    loop {
        let e = tokio::time::timeout_at(deadline, links.recv())
            .await
            .expect("link restored")
            .unwrap();
        if e.change == LinkChange::Restored && e.player_number == 2 {
            assert!(e.silent_for_s >= 1.0);
            break;
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_bridge_mirrors_the_team_model_and_the_game_state_into_the_dr() {
    use interfaces::msg::dr::{AttrValue, DrChange, GetNodeRequest};
    let ns = unique_namespace("nao-dr");
    let dir = scratch(&ns);
    let (debug, gc, cmd) = (free_udp_port(), free_udp_port(), free_udp_port());
    let manifest = dir.join("nao_dr.toml");
    std::fs::write(
        &manifest,
        format!(
            r#"
[[component]]
name = "deep_representation"
binary = "{dr}"
args = ["--scene", "coach"]

[[component]]
name = "spl_field"
binary = "{field}"
args = ["--controlled", "127.0.0.2", "--teammate", "127.0.0.3", "--debug-port", "{debug}",
        "--gamecontroller-port", "{gc}", "--command-port", "{cmd}", "--pre-game-s", "1"]

[[component]]
name = "nao_bridge"
binary = "{bridge}"
args = ["--robot", "127.0.0.2", "--teammate", "127.0.0.3", "--debug-port", "{debug}",
        "--gamecontroller-port", "{gc}", "--command-port", "{cmd}", "--dr-updates",
        "--dr-propose-via", "dr"]
depends_on = ["deep_representation"]
external_inputs = ["nao/command"]
"#,
            dr = bin("deep_representation").display(),
            field = bin("spl_field").display(),
            bridge = bin("nao_bridge").display(),
        ),
    )
    .unwrap();
    let launch = Launch::start(&manifest, &ns, &[]);
    launch
        .lines
        .wait_for("bridge up", Duration::from_secs(30), |l| {
            l.contains("nao_bridge is up")
        });
    let bus = Bus::open(&launch.connect_args(), "test-nao-dr")
        .await
        .unwrap();
    let truth = bus.subscriber(&topics::SIM_FIELD_TRUTH).await.unwrap();
    let changes = bus.subscriber(&topics::DR_CHANGES).await.unwrap();
    let node = |name: &str| GetNodeRequest {
        name: name.into(),
        ..Default::default()
    };
    // The controlled robot's node follows the simulated robot (through its debug packets, the
    // fusion and the mirror), and the field carries the game state.
    let deadline = tokio::time::Instant::now() + Duration::from_secs(20);
    loop {
        assert!(
            tokio::time::Instant::now() < deadline,
            "the DR never matched the field; output:\n{}",
            launch.lines.all().join("\n")
        );
        tokio::time::sleep(Duration::from_millis(300)).await;
        let Some(t) = truth.latest() else { continue };
        let (Ok(robot), Ok(field)) = (
            bus.call(&topics::DR_GET_NODE, &node("nao_2"), Duration::from_secs(1))
                .await,
            bus.call(&topics::DR_GET_NODE, &node("field"), Duration::from_secs(1))
                .await,
        ) else {
            continue;
        };
        let [x, y, _] = robot.pose.translation_m;
        let off_m = ((x - t.controlled.x_mm as f64 / 1000.0).powi(2)
            + (y - t.controlled.y_mm as f64 / 1000.0).powi(2))
        .sqrt();
        let state = field
            .attributes
            .iter()
            .find(|a| a.key == "game_state")
            .map(|a| a.value.clone());
        if off_m < 0.3 && matches!(state, Some(AttrValue::Text(_))) {
            break;
        }
    }

    // The obstacles the robots see (the opponents, goalposts) become nodes of the field, with
    // their type and last-seen time...
    let obstacle_changes = |kind: &str, within: Duration| {
        let deadline = tokio::time::Instant::now() + within;
        let changes = &changes;
        let kind = kind.to_string();
        let lines = &launch.lines;
        async move {
            let mut names = std::collections::BTreeSet::new();
            loop {
                let left = deadline.saturating_duration_since(tokio::time::Instant::now());
                let c: DrChange = match tokio::time::timeout(left, changes.recv()).await {
                    Ok(c) => c.unwrap(),
                    Err(_) if !names.is_empty() => return names,
                    Err(_) => panic!(
                        "no obstacle {kind} in the DR; output:\n{}",
                        lines.all().join("\n")
                    ),
                };
                if c.event.kind() == kind && c.event.node().starts_with("obstacle_") {
                    names.insert(c.event.node().to_string());
                    // Collect what else comes within a second.
                    let soon = tokio::time::Instant::now() + Duration::from_secs(1);
                    return loop {
                        match tokio::time::timeout_at(soon, changes.recv()).await {
                            Ok(Ok(c))
                                if c.event.kind() == kind
                                    && c.event.node().starts_with("obstacle_") =>
                            {
                                names.insert(c.event.node().to_string());
                            }
                            Ok(_) => {}
                            Err(_) => break names,
                        }
                    };
                }
            }
        }
    };
    let added = obstacle_changes("node_added", Duration::from_secs(20)).await;
    let first = added.iter().next().unwrap().clone();
    let info = bus
        .call(&topics::DR_GET_NODE, &node(&first), Duration::from_secs(2))
        .await
        .unwrap();
    assert_eq!(info.node_type, "object");
    assert_eq!(info.parent, "field");
    let attr = |k: &str| {
        info.attributes
            .iter()
            .find(|a| a.key == k)
            .map(|a| a.value.clone())
    };
    assert!(
        matches!(attr("obstacle_type"), Some(AttrValue::Text(t)) if ["opponent", "goalpost", "teammate", "fallen_opponent"].contains(&t.as_str())),
        "{info:?}"
    );
    // (The first update may still be on its way.)
    let deadline = tokio::time::Instant::now() + Duration::from_secs(5);
    let info = loop {
        let i = bus
            .call(&topics::DR_GET_NODE, &node(&first), Duration::from_secs(1))
            .await
            .unwrap();
        if i.attributes.iter().any(|a| a.key == "last_seen_ns") {
            break i;
        }
        assert!(
            tokio::time::Instant::now() < deadline,
            "no last-seen time: {i:?}"
        );
        tokio::time::sleep(Duration::from_millis(200)).await;
    };
    assert!(
        info.attributes.iter().any(|a| a.key == "seen_age_s"
            && matches!(a.value, AttrValue::Float(s) if (0.0..3.5).contains(&s))),
        "{info:?}"
    );
    println!("obstacle nodes added: {added:?}");

    // ... and go when nobody has seen them for the fusion's 3 s: the field stops sending.
    let field = eventually("field pid", Duration::from_secs(10), || {
        component_pid(&launch, "spl_field")
    });
    signal(field, "STOP");
    let mut removed = std::collections::BTreeSet::new();
    let deadline = tokio::time::Instant::now() + Duration::from_secs(20);
    while removed.len() < added.len() {
        let left = deadline.saturating_duration_since(tokio::time::Instant::now());
        match tokio::time::timeout(left, changes.recv()).await {
            Ok(Ok(c))
                if c.event.kind() == "node_removed" && c.event.node().starts_with("obstacle_") =>
            {
                removed.insert(c.event.node().to_string());
            }
            Ok(_) => {}
            Err(_) => {
                signal(field, "CONT");
                panic!("removed only {removed:?} of {added:?}");
            }
        }
    }
    assert!(
        added.is_subset(&removed),
        "added {added:?}, removed {removed:?}"
    );
    assert!(
        bus.call(&topics::DR_GET_NODE, &node(&first), Duration::from_secs(2))
            .await
            .is_err(),
        "{first} is still in the DR"
    );
    // The field comes back: so do the obstacles.
    signal(field, "CONT");
    let again = obstacle_changes("node_added", Duration::from_secs(20)).await;
    assert!(!again.is_empty());
}
