#![allow(clippy::unwrap_used)]
use super::*;

fn load(text: &str) -> Result<Manifest, Problems> {
    static N: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
    let dir = std::env::temp_dir().join(format!(
        "robocog-manifest-{}-{}",
        std::process::id(),
        N.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
    ));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join("g.toml");
    std::fs::write(&p, text).unwrap();
    let m = Manifest::load(&p, &Overrides::default());
    std::fs::remove_dir_all(&dir).unwrap();
    m
}

const MACHINES: &str = r#"
[graph]
certs = "certs"
[machines.robot]
router = "tls/10.0.0.2:7447"
[machines.speech]
router = "tls/10.0.0.3:7447"
"#;

#[test]
fn components_are_placed_on_the_declared_machines() {
    let m = load(&format!(
        "{MACHINES}
[[component]]
name = \"a\"
binary = \"true\"
machine = \"speech\"
hardware = [\"serial:/dev/ttyUSB0\"]
[[component]]
name = \"b\"
binary = \"true\"
machine = \"robot\"
hardware = [\"serial:/dev/ttyUSB0\"]
[[component]]
name = \"c\"
binary = \"true\"
"
    ))
    .unwrap();
    let names: Vec<&str> = m.machines.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["robot", "speech"]);
    assert_eq!(m.component("a").unwrap().machine.as_deref(), Some("speech"));
    assert_eq!(m.component("c").unwrap().machine, None);
    assert!(m.certs.unwrap().ends_with("certs"));
}

#[test]
fn bad_placement_is_an_error_at_its_line() {
    let e = load(&format!(
        "{MACHINES}
[[component]]
name = \"a\"
binary = \"true\"
machine = \"field\"
[[component]]
name = \"b\"
binary = \"true\"
machine = \"robot\"
hardware = [\"serial:/dev/ttyUSB0\"]
[[component]]
name = \"c\"
binary = \"true\"
machine = \"robot\"
hardware = [\"serial:/dev/ttyUSB0\"]
"
    ))
    .unwrap_err()
    .to_string();
    assert!(
        e.contains(
            ":12: component \"a\" is placed on unknown machine \"field\" (machines: robot, speech)"
        ),
        "{e}"
    );
    assert!(
        e.contains(
            "hardware \"serial:/dev/ttyUSB0\" on machine \"robot\" is claimed by both \"b\""
        ),
        "{e}"
    );
    let e = load("[[component]]\nname = \"a\"\nbinary = \"true\"\nmachine = \"robot\"\n")
        .unwrap_err()
        .to_string();
    assert!(e.contains("declares no [machines]"), "{e}");
}

#[test]
fn a_bus_off_the_host_is_secured_or_said_insecure() {
    let comp = "[[component]]\nname = \"a\"\nbinary = \"true\"\n";
    let plain = format!("[machines.robot]\nrouter = \"tcp/10.0.0.2:7447\"\n{comp}");
    let e = load(&plain).unwrap_err().to_string();
    assert!(
        e.contains("unencrypted") && e.contains("insecure_bus"),
        "{e}"
    );
    assert!(load(&format!("[graph]\ninsecure_bus = true\n{plain}")).is_ok());
    // Loopback stays plain and needs nothing.
    assert!(
        load(&format!(
            "[machines.robot]\nrouter = \"tcp/127.0.0.1:7447\"\n{comp}"
        ))
        .is_ok()
    );
    let e = load(&format!(
        "[machines.robot]\nrouter = \"tls/10.0.0.2:7447\"\n{comp}"
    ))
    .unwrap_err()
    .to_string();
    assert!(e.contains("names no certs folder"), "{e}");
    let e = load(&format!(
        "[graph]\ncerts = \"c\"\n[machines.Robot]\nrouter = \"tls/10.0.0.2:0\"\n{comp}"
    ))
    .unwrap_err()
    .to_string();
    assert!(e.contains("lowercase") && e.contains("fixed port"), "{e}");
    let e = load(&format!(
        "[machines.robot]\nrouter = \"udp/10.0.0.2:7447\"\n{comp}"
    ))
    .unwrap_err()
    .to_string();
    assert!(e.contains("not udp/"), "{e}");
}

#[test]
fn a_python_component_runs_as_its_module_under_the_python_interpreter() {
    let m = load(
        r#"
[[component]]
name = "tracker"
python = "my_tracker:Tracker"
args = ["--hue", "3"]
"#,
    )
    .unwrap();
    let c = &m.components[0];
    assert_eq!(c.binary, python_interpreter());
    assert_eq!(
        c.args,
        ["-m", "robocog", "run", "my_tracker:Tracker", "--hue", "3"]
    );
    for (text, why) in [
        ("binary = \"a\"\npython = \"b\"", "not both"),
        ("", "give `binary` (a program) or `python`"),
    ] {
        let e = load(&format!("[[component]]\nname = \"x\"\n{text}\n")).unwrap_err();
        assert!(e.to_string().contains(why), "{e}");
    }
}

#[test]
fn enabled_is_true_false_or_a_comparison_after_substitution() {
    let graph = |tracker: &str| {
        let text = format!(
            r#"
[vars]
tracker = "{tracker}"
[[component]]
name = "tracker"
binary = "ball_tracker"
enabled = "${{tracker}} == rust"
[[component]]
name = "tracker"
python = "robocog_ball_tracker"
enabled = "${{tracker}} != rust"
"#
        );
        load(&text)
    };
    let rust = graph("rust").unwrap();
    assert_eq!(rust.components.len(), 1);
    assert_eq!(rust.components[0].binary, "ball_tracker");
    let python = graph("python").unwrap();
    assert_eq!(python.components[0].args[3], "robocog_ball_tracker");
    assert_eq!(truth(" a == a "), Ok(true));
    assert_eq!(truth("a != a"), Ok(false));
    for bad in ["yes", "a ==", "== b", "a == b == c", "a = b"] {
        assert_eq!(truth(bad), Err(bad.to_string()), "{bad}");
    }
}
