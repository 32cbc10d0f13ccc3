use super::*;

fn config(args: &[&str]) -> Config {
    #[derive(clap::Parser)]
    struct Cli {
        #[command(flatten)]
        config: Config,
    }
    let mut all = vec!["audio_io"];
    all.extend_from_slice(args);
    <Cli as clap::Parser>::parse_from(all).config
}

#[test]
fn flags_out_of_range_are_refused_before_any_device_is_opened() {
    for (args, needle) in [
        (&["--no-capture", "--no-playback"][..], "nothing to do"),
        (&["--rate-hz", "100"][..], "--rate-hz"),
        (&["--chunk-ms", "0"][..], "--chunk-ms"),
        (&["--playback-buffer-ms", "5"][..], "--playback-buffer-ms"),
        (&["--reopen-s", "0"][..], "--reopen-s"),
        (&["--resume-after-s=-1"][..], "--resume-after-s"),
        (&["--resume-after-s", "11"][..], "--resume-after-s"),
        (
            &["--echo-cancel", "webrtc", "--no-playback"][..],
            "--echo-cancel needs both",
        ),
    ] {
        let e = prepare(config(args)).unwrap_err().to_string();
        assert!(e.contains(needle), "{args:?}: {e}");
    }
}

#[test]
fn no_sound_server_is_a_configuration_error_naming_the_address() {
    let e = prepare(config(&["--server", "unix:/nonexistent/robocog-audio"])).unwrap_err();
    assert!(
        e.downcast_ref::<interfaces::node::ConfigError>().is_some(),
        "{e:#}"
    );
    assert!(e.to_string().contains("/nonexistent/robocog-audio"), "{e}");
}

#[test]
fn chunks_hold_the_rate_times_the_length() {
    assert_eq!(config(&[]).chunk_frames(), 320);
    assert_eq!(
        config(&["--rate-hz", "48000", "--chunk-ms", "10"]).chunk_frames(),
        480
    );
}
