use super::*;
use audio::signal::{NoiseKind, NoiseRng, noise};

/// A burst of a 300 Hz tone with 3 harmonics, amplitude `amp`, lasting `secs`.
fn burst(secs: f64, amp: f64) -> Vec<i16> {
    (0..(secs * 16000.0) as usize)
        .map(|i| {
            let t = i as f64 / 16000.0;
            let s: f64 = (1..=3)
                .map(|k| (2.0 * std::f64::consts::PI * 300.0 * k as f64 * t).sin() / k as f64)
                .sum();
            (amp * s) as i16
        })
        .collect()
}

fn with_noise(mut signal: Vec<i16>, power: f64, seed: u64) -> Vec<i16> {
    let n = noise(
        signal.len(),
        NoiseKind::White,
        power,
        &mut NoiseRng::new(seed),
    );
    for (s, x) in signal.iter_mut().zip(n) {
        *s = (*s as f64 + x).round().clamp(-32768.0, 32767.0) as i16;
    }
    signal
}

#[test]
fn cuts_two_utterances_from_noise_with_their_times() {
    let mut stream = vec![0i16; 16000]; // 1 s quiet
    stream.extend(burst(0.8, 6000.0)); // 1.0 .. 1.8 s
    stream.extend(vec![0i16; 16000]); // 1 s quiet
    stream.extend(burst(0.5, 6000.0)); // 2.8 .. 3.3 s
    stream.extend(vec![0i16; 16000]);
    let stream = with_noise(stream, 1e-5, 1); // -50 dBFS noise
    let mut vad = Vad::new(VadConfig::default());
    let mut segs = vec![];
    // Odd chunk sizes on purpose.
    for c in stream.chunks(777) {
        segs.extend(vad.push(c));
    }
    assert!(vad.flush().is_none());
    assert_eq!(segs.len(), 2, "{segs:?}");
    let (a, b) = (&segs[0], &segs[1]);
    assert!(a.start_s() > 0.7 && a.start_s() < 1.0, "{}", a.start_s());
    assert!(a.end_s() > 1.8 && a.end_s() < 2.1, "{}", a.end_s());
    assert!(b.start_s() > 2.5 && b.start_s() < 2.8 && b.end_s() > 3.3 && b.end_s() < 3.6);
    assert_eq!(a.samples.len() as u64, a.end_sample - a.start_sample);
    assert!(!a.forced);
    // The floor tracks the noise (-50 dBFS).
    let floor = vad.floor_dbfs().unwrap();
    assert!((floor + 50.0).abs() < 3.0, "{floor}");
}

/// A microphone that starts in digital silence (a sound server's empty room, a source not
/// started yet) and then hears the room: the room's noise is its floor, not an utterance
/// that never ends; a burst in it is one utterance, with its times.
#[test]
fn the_room_after_digital_silence_is_the_floor_not_speech() {
    let mut stream = vec![0i16; 16000]; // 1 s of exact zeros
    let mut room = vec![0i16; 32000]; // 2 s of room
    room.extend(burst(0.8, 6000.0)); // 3.0 .. 3.8 s
    room.extend(vec![0i16; 16000]);
    stream.extend(with_noise(room, 1e-5, 3)); // -50 dBFS noise
    stream.extend(vec![0i16; 8000]); // silence again: the floor stays
    stream.extend(with_noise(vec![0i16; 16000], 1e-5, 4));
    let mut vad = Vad::new(VadConfig::default());
    let mut segs = vec![];
    for c in stream.chunks(320) {
        segs.extend(vad.push(c));
    }
    assert!(vad.flush().is_none());
    assert_eq!(segs.len(), 1, "{segs:?}");
    let a = &segs[0];
    assert!(!a.forced);
    assert!(a.start_s() > 2.7 && a.start_s() < 3.0, "{}", a.start_s());
    assert!(a.end_s() > 3.8 && a.end_s() < 4.1, "{}", a.end_s());
    let floor = vad.floor_dbfs().unwrap();
    assert!((floor + 50.0).abs() < 3.0, "{floor}");
}

/// An echo canceller's output: digital silence, then the room's noise from the middle of a
/// frame on (20 samples of it in the first). That frame is no measure of the room: a floor
/// set from it would sit 9 dB under the noise, which would be heard as an utterance.
#[test]
fn noise_starting_inside_a_frame_or_fading_in_after_digital_silence_is_the_floor() {
    /// The stream in 20 ms chunks: the utterances cut from it (times) and the floor.
    fn heard(stream: &[i16]) -> (Vec<(f64, f64)>, f64) {
        let mut vad = Vad::new(VadConfig::default());
        let mut segs = vec![];
        for c in stream.chunks(320) {
            segs.extend(vad.push(c));
        }
        segs.extend(vad.flush());
        let times = segs.iter().map(|s| (s.start_s(), s.end_s())).collect();
        (times, vad.floor_dbfs().unwrap())
    }
    let mut stream = vec![0i16; 16000 + 140];
    let p = 10f64.powf(-6.2); // -62 dBFS
    stream.extend(with_noise(vec![0i16; 32000], p, 5));
    let (times, floor) = heard(&stream);
    assert!(
        times.is_empty(),
        "utterances in the room's noise: {times:?}"
    );
    assert!((floor + 62.0).abs() < 3.0, "{floor}");

    // The same noise fading in over 30 ms (no frame of it partly silent): the floor is the
    // room's, not the fade's first frame.
    let mut stream = vec![0i16; 16000];
    let mut room = with_noise(vec![0i16; 32000], p, 6);
    for (k, x) in room.iter_mut().take(480).enumerate() {
        *x = (f64::from(*x) * (k + 1) as f64 / 480.0).round() as i16;
    }
    stream.extend(room);
    let (times, floor) = heard(&stream);
    assert!(
        times.is_empty(),
        "utterances in the fading-in noise: {times:?}"
    );
    assert!((floor + 62.0).abs() < 3.0, "{floor}");
}

/// A fan beside the robot: its power is low-frequency, so its 10 ms levels swing by several
/// dB where white noise's hardly move. A floor that followed the quietest frames sat under
/// most of them, and in a continuous stream every utterance ran to `max_utterance_s`. The
/// fan alone (at -45 dBFS, five fans of their own cut-off and blade tone) is no speech, and
/// bursts 10 dB over it are cut with their times.
#[test]
fn a_fan_is_the_floor_and_speech_over_it_ends_when_it_ends() {
    use audio::signal::{NoiseKind, active_power};
    let p_fan = 10f64.powf(-4.5);
    for seed in 0..5u64 {
        let n = 40 * 16_000;
        let fan = noise(n, NoiseKind::Fan, p_fan, &mut NoiseRng::new(100 + seed));
        let b = burst(0.8, 6000.0);
        let g = (10.0 * p_fan / active_power(&b)).sqrt();
        // Bursts at 10, 14, ..., 38 s: the first 10 s are the fan alone.
        let starts: Vec<usize> = (0..8).map(|k| (10 + 4 * k) * 16_000).collect();
        let mut stream: Vec<i16> = fan
            .iter()
            .map(|x| x.round().clamp(-32768.0, 32767.0) as i16)
            .collect();
        for &at in &starts {
            for (i, &x) in b.iter().enumerate() {
                let y = f64::from(stream[at + i]) + f64::from(x) * g;
                stream[at + i] = y.round().clamp(-32768.0, 32767.0) as i16;
            }
        }
        let mut vad = Vad::new(VadConfig::default());
        let mut segs = vec![];
        for c in stream.chunks(320) {
            segs.extend(vad.push(c));
        }
        segs.extend(vad.flush());
        let times: Vec<(f64, f64, bool)> = segs
            .iter()
            .map(|s| (s.start_s(), s.end_s(), s.forced))
            .collect();
        assert!(
            segs.iter().all(|s| !s.forced),
            "fan {seed}: utterances ran to the limit: {times:?} (floor {:?})",
            vad.floor_dbfs()
        );
        assert_eq!(segs.len(), starts.len(), "fan {seed}: {times:?}");
        assert!(
            segs.iter().all(|s| !s.over_talk),
            "fan {seed}: taken for talk"
        );
        for (s, &at) in segs.iter().zip(&starts) {
            let t = at as f64 / 16_000.0;
            assert!(
                s.start_s() > t - 0.4 && s.start_s() < t + 0.1,
                "fan {seed}: {times:?}"
            );
            assert!(
                s.end_s() > t + 0.8 && s.end_s() < t + 1.3,
                "fan {seed}: {times:?}"
            );
        }
    }
}

#[test]
fn clicks_are_dropped_long_speech_is_cut_and_silence_is_nothing() {
    let mut vad = Vad::new(VadConfig::default());
    let mut stream = vec![0i16; 8000];
    stream.extend(burst(0.05, 8000.0));
    stream.extend(vec![0i16; 16000]);
    assert!(vad.push(&stream).is_empty());
    assert_eq!(vad.dropped_short, 1);

    let mut vad = Vad::new(VadConfig {
        max_utterance_s: 2.0,
        ..VadConfig::default()
    });
    let mut stream = vec![0i16; 8000];
    stream.extend(burst(5.0, 6000.0));
    let segs = vad.push(&stream);
    assert!(!segs.is_empty() && segs[0].forced, "{segs:?}");
    assert!((segs[0].end_s() - segs[0].start_s() - 2.0).abs() < 0.02);

    let mut vad = Vad::new(VadConfig::default());
    assert!(vad.push(&vec![0i16; 48000]).is_empty());
    assert!(vad.push(&[]).is_empty());
    assert!(!vad.in_speech());
    // Speech at the very end of a stream comes out on flush.
    let mut s = vec![0i16; 8000];
    s.extend(burst(0.6, 6000.0));
    assert!(vad.push(&s).is_empty());
    assert!(vad.in_speech());
    assert!(vad.flush().is_some());
}

/// Three people talking in the room, and then someone saying a command over them, 10 dB
/// louder: once the detector has heard a few seconds of the talk it cuts no utterance out
/// of it, and the command is one utterance with its times. Without the background's
/// threshold (the floor alone) the same talk opens utterance after utterance.
#[test]
fn background_talk_is_not_taken_for_speech_and_a_command_over_it_is() {
    use audio::signal::{active_power, babble, power};
    use audio::synth::{Voice, synthesize_16k, talker};
    let sentences = [
        "the bakery on the corner opens at seven every morning",
        "we drove along the coast and stopped for lunch in a small village",
        "he keeps his old records in a box under the stairs",
        "the garden looks lovely after the rain in spring",
    ];
    let talkers: Vec<Vec<i16>> = ["en-us+m2", "en-gb+f5", "en-us+f1"]
        .iter()
        .enumerate()
        .map(|(k, v)| {
            let voice = Voice {
                voice: (*v).into(),
                speed_wpm: 160 + 10 * k as u32,
                pitch: 40 + 5 * k as u8,
            };
            talker(&voice, &sentences, k).expect("espeak-ng")
        })
        .collect();
    let command = synthesize_16k("touch the ball", &Voice::default()).expect("espeak-ng");
    let talk_s = 12.0;
    let n = (talk_s * 16_000.0) as usize;
    // The talk at -30 dBFS, the command 10 dB over it, said 8 s into the talk.
    let b = babble(&talkers, n, 1e-3, &mut NoiseRng::new(5));
    let g_cmd = (1e-2 / active_power(&command)).sqrt();
    let at = 8 * 16_000;
    let mut stream = with_noise(vec![0i16; 16_000], 1e-6, 9); // 1 s of a quiet room
    stream.extend((0..n).map(|i| {
        let c = if i >= at && i - at < command.len() {
            f64::from(command[i - at]) * g_cmd
        } else {
            0.0
        };
        (b[i] + c).round().clamp(-32768.0, 32767.0) as i16
    }));
    assert!((10.0 * power(&stream[16_000..16_000 + at]).log10() + 30.0).abs() < 1.5);
    let cut = |cfg: VadConfig| {
        let mut vad = Vad::new(cfg);
        let mut segs = vec![];
        for c in stream.chunks(320) {
            segs.extend(vad.push(c));
        }
        segs.extend(vad.flush());
        (segs, vad.dropped_short)
    };
    let command_start = 1.0 + 8.0;
    // Where its sound ends (espeak-ng ends a sentence with silence).
    let loud_until = command
        .iter()
        .rposition(|x| x.unsigned_abs() > 300)
        .unwrap_or(0);
    let command_end = command_start + loud_until as f64 / 16_000.0;
    let (segs, _) = cut(VadConfig::default());
    // The talk's start, heard against a quiet room, is speech at first: it is cut at
    // `max_utterance_s` and from then on is the background. After that the only utterance
    // is the command.
    let first = &segs[0];
    assert!(
        first.forced && first.start_s() < 1.1,
        "{:?}",
        (first.start_s(), first.end_s())
    );
    let later: Vec<&Segment> = segs
        .iter()
        .skip(1)
        .filter(|s| s.end_s() > first.end_s())
        .collect();
    assert_eq!(segs.len(), later.len() + 1);
    assert_eq!(
        later.len(),
        1,
        "{:?}",
        segs.iter()
            .map(|s| (s.start_s(), s.end_s()))
            .collect::<Vec<_>>()
    );
    let c = later[0];
    assert!(!c.forced);
    assert!(c.over_talk, "the command is not marked as said over talk");
    assert!(
        c.start_s() > command_start - 0.4 && c.start_s() < command_start + 0.15,
        "starts at {:.2} s, the command at {command_start:.2} s",
        c.start_s()
    );
    assert!(
        c.end_s() > command_end - 0.1 && c.end_s() < command_end + 0.6,
        "ends at {:.2} s, the command at {command_end:.2} s",
        c.end_s()
    );
    // The floor alone takes the talk for speech: utterance after utterance cut at
    // `max_utterance_s`, and the command is no utterance of its own.
    let (segs, _) = cut(VadConfig {
        background_margin_db: f64::NEG_INFINITY,
        ..VadConfig::default()
    });
    let times: Vec<(f64, f64, bool)> = segs
        .iter()
        .map(|s| (s.start_s(), s.end_s(), s.forced))
        .collect();
    assert!(segs.iter().filter(|s| s.forced).count() >= 2, "{times:?}");
    assert!(
        !segs.iter().any(|s| !s.forced
            && (s.start_s() - command_start).abs() < 0.4
            && (s.end_s() - command_end).abs() < 0.6),
        "without the background threshold the command was cut alone: {times:?}"
    );
}

/// Push-to-talk: talk as loud as hers, heard while the key was up (from elsewhere), is the
/// background. With the key held she opens one utterance over her whole command; judged by
/// the background's threshold alone, her command does not stand out of talk as loud as it.
#[test]
fn with_the_key_held_her_command_opens_over_talk_as_loud_as_hers() {
    use audio::signal::active_power;
    use audio::synth::{Voice, synthesize_16k};
    let other = synthesize_16k(
        "we drove along the coast and stopped for lunch in a small village",
        &Voice {
            voice: "en-gb+f5".into(),
            speed_wpm: 170,
            pitch: 45,
        },
    )
    .expect("espeak-ng");
    let command = synthesize_16k("pass the ball", &Voice::default()).expect("espeak-ng");
    let level = |x: &[i16]| {
        let g = (1e-2 / active_power(x)).sqrt();
        x.iter()
            .map(move |s| f64::from(*s) * g)
            .collect::<Vec<f64>>()
    };
    let quiet = |s: f64| vec![0.0; (s * 16_000.0) as usize];
    let mut stream: Vec<f64> = quiet(0.5);
    stream.extend(level(&other));
    let key_down = stream.len();
    stream.extend(quiet(0.2));
    let command_start = stream.len();
    stream.extend(level(&command));
    let command_end = command_start
        + command
            .iter()
            .rposition(|x| x.unsigned_abs() > 300)
            .unwrap_or(0);
    stream.extend(quiet(1.0));
    let stream: Vec<i16> = stream
        .iter()
        .map(|s| s.round().clamp(-32768.0, 32767.0) as i16)
        .collect();
    let stream = with_noise(stream, 1e-6, 4);
    let cut = |keyed: bool| {
        let mut vad = Vad::new(VadConfig::default());
        let mut segs = vec![];
        for (k, c) in stream.chunks(320).enumerate() {
            let held = k * 320 >= key_down;
            vad.set_elsewhere(!held);
            vad.set_hers(keyed && held);
            segs.extend(vad.push(c));
        }
        segs.extend(vad.flush());
        segs
    };
    let whole = |s: &Segment| {
        s.start_sample <= command_start as u64 + 1600 && s.end_sample >= command_end as u64 - 1600
    };
    let keyed = cut(true);
    assert_eq!(keyed.len(), 1, "{keyed:?}");
    assert!(
        whole(&keyed[0]),
        "{keyed:?} (her command: {command_start}..{command_end})"
    );
    let unkeyed = cut(false);
    assert!(!unkeyed.iter().any(whole), "{unkeyed:?}");
}
