#![allow(clippy::unwrap_used)]
//! `robocog topic`, `robocog service` and `robocog component` against a running graph, with no
//! opt-in.

use robocog_tests::*;
use std::time::Duration;

#[test]
fn topic_tools_see_and_poke_a_running_graph() {
    let ns = unique_namespace("topic");
    let m = write_manifest(
        &scratch(&ns),
        "graph.toml",
        r#"
[[component]]
name = "talker"
binary = "@FIXTURE@"
args = ["--role", "talker", "--rate", "20"]

[[component]]
name = "listener"
binary = "@FIXTURE@"
args = ["--role", "listener"]
"#,
    );
    let launch = Launch::start(&m, &ns, &[]);
    launch
        .lines
        .wait_for("talker up", Duration::from_secs(20), |l| {
            l.contains("talker is up")
        });
    launch
        .lines
        .wait_for("listener up", Duration::from_secs(20), |l| {
            l.contains("listener is up")
        });
    let t = Duration::from_secs(30);

    // echo decodes the payload and prints JSON.
    let out = launch.robocog(
        &[
            "topic",
            "echo",
            "chatter",
            "--count",
            "2",
            "--timeout",
            "10",
        ],
        t,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    let first: serde_json::Value = serde_json::from_str(stdout.lines().next().unwrap()).unwrap();
    assert!(
        first["text"].as_str().unwrap().starts_with("hello "),
        "{first}"
    );
    assert!(first["header"]["stamp_ns"].as_i64().unwrap() > 0);
    // The sequence number, which travels beside the payload, is the talker's count.
    let n: u64 = first["text"].as_str().unwrap()["hello ".len()..]
        .parse()
        .unwrap();
    assert_eq!(first["header"]["seq"], n, "{first}");

    // --ros: as a ROS 2 decoder reads the same payload (a std_msgs/Header, no sequence number).
    let out = launch.robocog(
        &[
            "topic",
            "echo",
            "chatter",
            "--ros",
            "--count",
            "1",
            "--timeout",
            "10",
        ],
        t,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let ros: serde_json::Value =
        serde_json::from_str(String::from_utf8_lossy(&out.stdout).lines().next().unwrap()).unwrap();
    assert!(
        ros["header"]["stamp"]["sec"].as_i64().unwrap() > 1_700_000_000,
        "{ros}"
    );
    assert!(ros["header"]["stamp"]["nanosec"].as_u64().unwrap() < 1_000_000_000);
    assert!(ros["header"].get("seq").is_none(), "{ros}");
    assert!(ros["text"].as_str().unwrap().starts_with("hello "), "{ros}");

    // list shows the topic with its type and both ends.
    let out = launch.robocog(&["topic", "list", "--json"], t);
    let list: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let chatter = list
        .as_array()
        .unwrap()
        .iter()
        .find(|x| x["topic"] == "chatter")
        .expect("chatter listed");
    assert_eq!(chatter["types"][0], "robocog.Text");
    assert!(
        chatter["publishers"]
            .as_array()
            .unwrap()
            .iter()
            .any(|p| p == "talker")
    );
    assert!(
        chatter["subscribers"]
            .as_array()
            .unwrap()
            .iter()
            .any(|p| p == "listener")
    );

    // hz measures the talker's messages: a rate from the intervals it saw, between the longest
    // and the shortest of them, and their spread. (How close the talker keeps to its 20 Hz on a
    // busy machine is a benchmark's figure, not this test's.)
    let out = launch.robocog(&["topic", "hz", "chatter", "--duration", "3", "--json"], t);
    let last: serde_json::Value =
        serde_json::from_str(String::from_utf8_lossy(&out.stdout).lines().last().unwrap()).unwrap();
    let num = |k: &str| {
        last[k]
            .as_f64()
            .unwrap_or_else(|| panic!("no {k} in {last}"))
    };
    let (rate, min, max, jitter) = (
        num("rate_hz"),
        num("min_s"),
        num("max_s"),
        num("jitter_std_s"),
    );
    assert!(
        num("window") >= 10.0,
        "a window of intervals over 3 s: {last}"
    );
    assert!(num("messages") > num("window"), "{last}");
    assert!(
        rate > 0.0 && min > 0.0 && min <= 1.0 / rate && 1.0 / rate <= max,
        "the mean interval lies between the shortest and the longest: {last}"
    );
    assert!(jitter.is_finite() && jitter <= max - min, "{last}");

    // info shows the type and its shape.
    let out = launch.robocog(&["topic", "info", "chatter"], t);
    let info = String::from_utf8_lossy(&out.stdout);
    assert!(
        info.contains("robocog.Text") && info.contains("\"text\""),
        "{info}"
    );

    // pub reaches the listener; a misspelt field is refused.
    let out = launch.robocog(
        &[
            "topic",
            "pub",
            "chatter",
            r#"{"text": "from the command line"}"#,
        ],
        t,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    launch
        .lines
        .wait_for("the published message", Duration::from_secs(10), |l| {
            l.contains("received: from the command line")
        });
    let out = launch.robocog(&["topic", "pub", "chatter", r#"{"txt": "typo"}"#], t);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("no field \"txt\""));

    // component list shows both, on this host.
    let out = launch.robocog(&["component", "list", "--json"], t);
    let comps: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let names: Vec<&str> = comps
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["name"].as_str().unwrap())
        .collect();
    assert!(
        names.contains(&"talker") && names.contains(&"listener"),
        "{names:?}"
    );
}

/// `robocog service list | info | call` against an echo server: the service found from the graph
/// with its types and server, a call answered with the value, an error reply with its code, and
/// wrong requests refused before anything is sent.
#[test]
fn service_tools_list_describe_and_call_a_running_graph() {
    let ns = unique_namespace("service");
    let m = write_manifest(
        &scratch(&ns),
        "graph.toml",
        r#"
[[component]]
name = "echoer"
binary = "@FIXTURE@"
args = ["--role", "echo-server"]
"#,
    );
    let launch = Launch::start(&m, &ns, &[]);
    launch
        .lines
        .wait_for("echoer up", Duration::from_secs(20), |l| {
            l.contains("echoer is up")
        });
    let t = Duration::from_secs(30);
    let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();

    let out = launch.robocog(&["service", "list", "--json"], t);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let list: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let echo = list
        .as_array()
        .unwrap()
        .iter()
        .find(|x| x["service"] == "echo")
        .unwrap_or_else(|| panic!("echo listed: {list}"));
    assert_eq!(echo["request"][0], "robocog.Text");
    assert_eq!(echo["reply"][0], "robocog.Text");
    assert_eq!(echo["servers"][0], "echoer");
    let table = text(&launch.robocog(&["service", "list"], t).stdout);
    assert!(
        table
            .lines()
            .any(|l| l.starts_with("echo ") && l.contains("robocog.Text") && l.contains("echoer")),
        "{table}"
    );

    let out = launch.robocog(&["service", "info", "echo"], t);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let info = text(&out.stdout);
    assert!(
        info.contains("servers:  echoer") && info.contains("shape of robocog.Text"),
        "{info}"
    );

    // A call: the reply as one line of JSON.
    let out = launch.robocog(&["service", "call", "echo", r#"{"text": "hello"}"#], t);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let reply: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(reply["text"], "HELLO");

    // The server's error: its code and message, exit 1.
    let out = launch.robocog(&["service", "call", "echo"], t);
    assert_eq!(out.status.code(), Some(1));
    let err = text(&out.stderr);
    assert!(
        err.contains("BadRequest") && err.contains("nothing to echo"),
        "{err}"
    );

    // Wrong requests: refused with the reason, exit 2.
    for (args, why) in [
        (
            vec!["service", "call", "echo", r#"{"txt": "x"}"#],
            "no field \"txt\"",
        ),
        (vec!["service", "call", "echo", "hello"], "not JSON"),
        (
            vec!["service", "call", "Echo!", "{}"],
            "invalid service name",
        ),
    ] {
        let out = launch.robocog(&args, t);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = text(&out.stderr);
        assert!(err.contains(why), "{args:?}: {err}");
    }
    // Nobody serves it: exit 1, said so.
    let out = launch.robocog(&["service", "call", "nobody/here"], t);
    assert_eq!(out.status.code(), Some(1));
    assert!(text(&out.stderr).contains("serves \"nobody/here\""));
}
