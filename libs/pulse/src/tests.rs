use super::*;
use crate::echo::{derived_name, module_value};
use crate::stream::spec;

fn sample() -> Devices {
    Devices {
        server: "pulseaudio 16.1".into(),
        default_source: "mic".into(),
        default_sink: "room".into(),
        sources: vec![
            Device {
                name: "room.monitor".into(),
                description: "Monitor of Room".into(),
                rate_hz: 48_000,
                channels: 2,
                channel_map: "front-left,front-right".into(),
                monitor: true,
            },
            Device {
                name: "mic".into(),
                description: "Microphone".into(),
                rate_hz: 48_000,
                channels: 2,
                channel_map: "front-left,front-right".into(),
                monitor: false,
            },
        ],
        sinks: vec![],
    }
}

#[test]
fn names_and_defaults_are_found_and_listed() {
    let d = sample();
    assert!(d.has(Kind::Source, "mic"));
    assert!(d.has(Kind::Source, DEFAULT_SOURCE));
    assert!(!d.has(Kind::Source, "usb-mic"));
    let l = d.listing(Kind::Source);
    assert!(
        l.contains("mic [default] (Microphone, 48000 Hz, 2 ch)"),
        "{l}"
    );
    assert!(
        l.contains("room.monitor (Monitor of Room, 48000 Hz, 2 ch, monitor of a sink)"),
        "{l}"
    );
    assert_eq!(d.listing(Kind::Sink), "  (none)");
    assert_eq!(
        d.find(Kind::Source, DEFAULT_SOURCE)
            .map(|d| d.name.as_str()),
        Some("mic")
    );
    assert_eq!(
        d.find(Kind::Source, "room.monitor")
            .map(|d| d.channel_map.as_str()),
        Some("front-left,front-right")
    );
    assert!(d.find(Kind::Sink, DEFAULT_SINK).is_none());
}

#[test]
fn a_channel_map_the_server_would_not_know_is_refused_before_it_is_asked() {
    for map in ["", "aux0,not-a-position", "front-left,,front-right"] {
        let e = Capture::open_mapped(
            Some("unix:/nonexistent/socket"),
            "mic",
            16_000,
            map,
            320,
            "t",
        )
        .unwrap_err();
        assert!(
            matches!(&e, Error::Invalid { what, .. } if what == "channel map"),
            "{map:?}: {e}"
        );
    }
}

#[test]
fn bad_formats_are_refused_before_the_server_is_asked() {
    assert!(matches!(spec(0, 1), Err(Error::Invalid { .. })));
    assert!(matches!(spec(16_000, 0), Err(Error::Invalid { .. })));
    assert!(spec(16_000, 1).is_ok());
    let e = Capture::open(Some("unix:/nonexistent/socket"), "mic", 16_000, 1, 0, "t").unwrap_err();
    assert!(e.is_configuration(), "{e}");
}

#[test]
fn an_echo_canceller_takes_one_word_device_names_and_names_its_own_after_them() {
    assert_eq!(
        module_value("m", "alsa_input.usb-1").unwrap(),
        "alsa_input.usb-1"
    );
    for bad in ["", "two words", "quo\"te", "back\\slash"] {
        assert!(
            matches!(module_value("m", bad), Err(Error::Invalid { .. })),
            "{bad:?}"
        );
    }
    assert_eq!(derived_name("room.monitor"), "room.monitor");
    assert_eq!(derived_name("a:b/c"), "a_b_c");
    // Refused before the server is asked.
    let e = EchoCanceller::load(Some("unix:/nonexistent/socket"), "two words", DEFAULT_SINK)
        .unwrap_err();
    assert!(e.is_configuration(), "{e}");
}

#[test]
fn no_server_is_an_error_that_names_the_address() {
    let e = devices(Some("unix:/nonexistent/robocog-test-socket")).unwrap_err();
    assert!(matches!(e, Error::NoServer { .. }), "{e}");
    assert!(
        e.to_string().contains("/nonexistent/robocog-test-socket"),
        "{e}"
    );
    assert!(!e.is_configuration());
}
