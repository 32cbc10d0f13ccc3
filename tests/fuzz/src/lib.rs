//! The fuzz targets: one function per parser that reads bytes robocog did not write itself, each
//! taking any input without panicking, hanging or allocating beyond a bound, and, where the
//! format has an encoder, checking that what decodes encodes back to the same value.
//!
//! The same bodies run two ways:
//! - coverage-guided, under libFuzzer (`libfuzzer/`, `scripts/fuzz <target> [seconds]`), with
//!   `-malloc_limit_mb` so that one allocation beyond the bound is a crash;
//! - briefly in the test suite (`tests/corpora.rs`): every committed corpus file and a few
//!   thousand seeded mutations of them, under an allocator that fails the test on an allocation
//!   beyond [`MAX_ALLOCATION`].
//!
//! Corpora: `corpus/<target>/`, seeded from real packets, files and messages and grown by the
//! long runs (the files libFuzzer found new coverage with; `scripts/fuzz` minimises them after
//! each run). An input that once crashed a target stays in `regressions/<target>/`, which the
//! minimiser does not touch, and the short runs replay it too.

use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};

/// The largest single allocation any target may make for one input (inputs are at most a few
/// kilobytes; a length field of 2^32-1 must never turn into a buffer of that size).
pub const MAX_ALLOCATION: usize = 64 << 20;

/// A target: its name (the folder of its corpus, the libFuzzer binary) and its body.
pub type Target = (&'static str, fn(&[u8]));

/// Every target.
pub const TARGETS: &[Target] = &[
    ("cdr", cdr),
    ("panel_request", panel_request),
    ("mcap", mcap),
    ("manifest", manifest),
    ("urdf", urdf),
    ("dynamixel", dynamixel),
    ("nao_command", nao_command),
    ("nao_debug", nao_debug),
    ("gamecontroller", gamecontroller),
];

/// The CDR decoding of every registered message type. The first byte picks the type, the rest
/// is the payload, as a subscriber or a service would receive it. What decodes must encode back
/// and decode to the same value; camera frames are also read in place (their borrowed view).
pub fn cdr(data: &[u8]) {
    let Some((&pick, payload)) = data.split_first() else {
        return;
    };
    let registry = interfaces::msg::REGISTRY;
    let entry = &registry[usize::from(pick) % registry.len()];
    if let Ok(json) = (entry.to_json)(payload) {
        // JSON cannot carry every value (a NaN becomes null): only what it can must round-trip.
        if let Ok(again) = (entry.from_json)(json.clone()) {
            let back = (entry.to_json)(&again);
            assert!(
                back.as_ref().is_ok_and(|b| *b == json),
                "{}: re-encoded payload decodes to {back:?}, not {json}",
                entry.name
            );
        }
    }
    let _ = interfaces::codec::decode_borrowed::<
        <interfaces::msg::vision::RgbdFrame as interfaces::Borrowable>::View<'_>,
    >(payload, "robocog.RgbdFrame");
}

/// The command panel's requests (the text of a WebSocket message from the browser).
pub fn panel_request(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    let _ = command_generator::protocol::parse_request(&text);
}

/// The MCAP reader of `robocog replay` and `robocog topic` on a damaged or foreign file: it reads
/// to the end, reporting damage, and never loops.
pub fn mcap(data: &[u8]) {
    let Some(path) = scratch_file("mcap", data) else {
        return;
    };
    if let Ok(reader) = robocog::mcap_io::RecordingReader::open(&path) {
        // Every item consumes at least one record; a file of n bytes has fewer than n records.
        let mut items = 0usize;
        for _ in reader {
            items += 1;
            assert!(items <= data.len() + 1, "the reader does not end");
        }
    }
    let _ = std::fs::remove_file(&path);
}

/// The launch manifest parser: strict TOML, vars, profiles, substitution, the structural checks.
pub fn manifest(data: &[u8]) {
    let Some(path) = scratch_file("toml", data) else {
        return;
    };
    let overrides = robocog::manifest::Overrides {
        profile: None,
        set: vec![("scenario".into(), "still".into())],
    };
    if let Ok(m) = robocog::manifest::Manifest::load(&path, &overrides) {
        let _ = m.start_order();
    }
    let _ = std::fs::remove_file(&path);
}

/// The URDF loader of the robot model (the IK, the joints, the camera, the viewer read it).
pub fn urdf(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    if let Ok(model) = robot_model::RobotModel::from_urdf_str(&text) {
        let _ = format!("{model:?}");
    }
}

/// The Dynamixel Protocol 2.0 stream decoder, as the serial line feeds it: packets, noise and
/// partial packets; each call consumes what it can and never more than it was given.
pub fn dynamixel(data: &[u8]) {
    use joint_motor::dynamixel::protocol::{Decoded, decode};
    let mut rest = data;
    // Each step drops at least one byte, so at most len + 1 steps.
    for _ in 0..=data.len() {
        let consumed = match decode(rest) {
            Decoded::Packet { consumed, .. } | Decoded::Invalid { consumed, .. } => consumed,
            Decoded::NeedMore => return,
        };
        assert!(
            (1..=rest.len()).contains(&consumed),
            "consumed {consumed} of {} bytes",
            rest.len()
        );
        rest = &rest[consumed..];
    }
    panic!("the decoder did not finish {} bytes", data.len());
}

/// The Nao link's command packet (coach to robot); what decodes encodes to the same command.
pub fn nao_command(data: &[u8]) {
    if let Ok(cmd) = spl::decode_command(data)
        && let Ok(bytes) = spl::encode_command(&cmd)
    {
        assert_eq!(spl::decode_command(&bytes).ok(), Some(cmd));
    }
}

/// The Nao link's debug packet (robot to coach: its local model).
pub fn nao_debug(data: &[u8]) {
    if let Ok(model) = spl::decode_debug(data)
        && let Ok(bytes) = spl::encode_debug(&model)
    {
        assert_eq!(spl::decode_debug(&bytes).ok(), Some(model));
    }
}

/// The GameController's state packet.
pub fn gamecontroller(data: &[u8]) {
    if let Ok(state) = spl::decode_gamecontroller(data)
        && let Ok(bytes) = spl::encode_gamecontroller(&state)
    {
        assert_eq!(spl::decode_gamecontroller(&bytes).ok(), Some(state));
    }
}

/// Write `data` to a file of this process and call in the system's temporary folder (the readers
/// under test take paths); the caller removes it.
fn scratch_file(ext: &str, data: &[u8]) -> Option<PathBuf> {
    static N: AtomicU64 = AtomicU64::new(0);
    let path = std::env::temp_dir().join(format!(
        "robocog-fuzz-{}-{}.{ext}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    let mut f = std::fs::File::create(&path).ok()?;
    f.write_all(data).ok()?;
    Some(path)
}

/// Seed inputs for `target`, made from the real thing: every message type's encoding, the
/// panel's documented requests, a recording written by the recorder, the shipped manifests, Loki's
/// URDF, Dynamixel packets, the SPL sample packets. `tests/corpora.rs` writes them into
/// `corpus/<target>/` (`--ignored write_seeds`); the long runs grow the corpora from there.
pub fn seeds(target: &str) -> Vec<(String, Vec<u8>)> {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let file = |rel: &str| std::fs::read(root.join(rel)).unwrap_or_default();
    match target {
        "cdr" => interfaces::msg::REGISTRY
            .iter()
            .enumerate()
            .filter_map(|(i, e)| {
                let payload = (e.from_json)((e.example)()).ok()?;
                let pick = u8::try_from(i).ok()?;
                Some((e.name.to_string(), [&[pick][..], &payload].concat()))
            })
            .collect(),
        "panel_request" => [
            r#"{"type":"command","id":1,"game":"touch","command":"TouchBall"}"#,
            r#"{"type":"command","id":2,"game":"coach","command":"GoToPosition","target":{"x_mm":1000,"y_mm":-500}}"#,
            r#"{"type":"nao","id":3,"body":"Dribble","head":"Scan"}"#,
            r#"{"type":"strategy","id":4,"strategy":"Passages"}"#,
            r#"{"type":"answer","id":5,"yes":true}"#,
        ]
        .iter()
        .enumerate()
        .map(|(i, s)| (format!("request-{i}"), s.as_bytes().to_vec()))
        .collect(),
        "mcap" => recording().map(|r| ("recording".to_string(), r)).into_iter().collect(),
        "manifest" => ["demo", "touch_the_ball", "nao_coach", "body_sim"]
            .iter()
            .map(|m| (m.to_string(), file(&format!("launch/{m}.toml"))))
            .collect(),
        "urdf" => vec![
            ("loki".into(), file("models/loki.urdf")),
            (
                "two_links".into(),
                br#"<robot name="r"><link name="a"/><link name="b"/><joint name="j" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>"#.to_vec(),
            ),
        ],
        "dynamixel" => {
            use joint_motor::dynamixel::protocol::{Instruction, Packet, read_params};
            let read = Packet::new(7, Instruction::Read, read_params(132, 4)).encode();
            let ping = Packet::new(1, Instruction::Ping, vec![]).encode();
            // Stuffing: a body that holds the header's bytes.
            let stuffed = Packet::new(2, Instruction::Write, vec![0xff, 0xff, 0xfd, 0x00]).encode();
            vec![
                ("read".into(), read.clone()),
                ("ping".into(), ping.clone()),
                ("stuffed".into(), stuffed),
                ("stream".into(), [&[0x13, 0xff][..], &read, &ping[..5], &read].concat()),
            ]
        }
        "nao_command" => {
            use interfaces::msg::nao::{FieldPoint, NaoBody, NaoCommand, NaoStrategy};
            let cmd = NaoCommand::body(NaoBody::GoToPosition, NaoStrategy::Default, FieldPoint::new(1000.0, -500.0));
            spl::encode_command(&cmd)
                .map(|b| ("go_to_position".to_string(), b.to_vec()))
                .into_iter()
                .collect()
        }
        "nao_debug" => vec![("debug".into(), spl::samples::debug_packet())],
        "gamecontroller" => vec![("playing".into(), spl::samples::gamecontroller_packet())],
        _ => Vec::new(),
    }
}

/// Whether `target`'s parser takes `data` as a whole, valid input (what a seed must be, or it
/// would fuzz nothing past the first check).
pub fn accepts(target: &str, data: &[u8]) -> bool {
    match target {
        "cdr" => data.split_first().is_some_and(|(&pick, payload)| {
            let registry = interfaces::msg::REGISTRY;
            (registry[usize::from(pick) % registry.len()].to_json)(payload).is_ok()
        }),
        "panel_request" => {
            command_generator::protocol::parse_request(&String::from_utf8_lossy(data)).is_ok()
        }
        "mcap" => scratch_file("mcap", data).is_some_and(|path| {
            let ok = robocog::mcap_io::RecordingReader::open(&path).is_ok_and(|r| {
                let items: Vec<_> = r.collect();
                !items.is_empty() && items.iter().all(Result::is_ok)
            });
            let _ = std::fs::remove_file(&path);
            ok
        }),
        "manifest" => scratch_file("toml", data).is_some_and(|path| {
            let ok = robocog::manifest::Manifest::load(&path, &Default::default()).is_ok();
            let _ = std::fs::remove_file(&path);
            ok
        }),
        "urdf" => robot_model::RobotModel::from_urdf_str(&String::from_utf8_lossy(data)).is_ok(),
        // A stream from the serial line: at least one packet in it.
        "dynamixel" => {
            use joint_motor::dynamixel::protocol::{Decoded, decode};
            let mut rest = data;
            loop {
                match decode(rest) {
                    Decoded::Packet { .. } => return true,
                    Decoded::Invalid { consumed, .. } => rest = &rest[consumed.min(rest.len())..],
                    Decoded::NeedMore => return false,
                }
            }
        }
        "nao_command" => spl::decode_command(data).is_ok(),
        "nao_debug" => spl::decode_debug(data).is_ok(),
        "gamecontroller" => spl::decode_gamecontroller(data).is_ok(),
        _ => false,
    }
}

/// A short recording as `robocog record` writes it: two topics, three messages.
fn recording() -> Option<Vec<u8>> {
    use interfaces::msg::std_msgs::Text;
    let path = scratch_file("mcap", &[])?;
    let mut w = robocog::mcap_io::RecordWriter::create(&path, "fuzz").ok()?;
    for (i, topic) in ["chatter", "chatter", "log"].iter().enumerate() {
        let msg = Text {
            text: format!("message {i}"),
            ..Text::default()
        };
        let payload = interfaces::codec::encode(&msg, "robocog.Text").ok()?;
        w.write(
            topic,
            "robocog.Text",
            1_000 + i as u64,
            Some(i as u64),
            &payload,
        )
        .ok()?;
    }
    w.finish(Default::default()).ok()?;
    let bytes = std::fs::read(&path).ok();
    let _ = std::fs::remove_file(&path);
    bytes
}
