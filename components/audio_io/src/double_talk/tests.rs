use super::levels::correlation;
use super::*;

const RATE: u32 = 16_000;
const FRAME: usize = 160;
const FRAME_NS: i64 = 10_000_000;

/// A frame at `db` dBFS (a square wave of that power), phase `k`.
fn frame_at(db: f64, k: usize) -> Vec<i16> {
    let a = 32768.0 * 10f64.powf(db / 20.0);
    (0..FRAME)
        .map(|i| if ((i + k) / 8).is_multiple_of(2) { a } else { -a } as i16)
        .collect()
}

/// A voice-like envelope for frame `k`: syllables of 15 frames between -45 and -20 dBFS.
fn voice(k: usize) -> f64 {
    let s = [-20.0, -24.0, -30.0, -45.0, -26.0, -21.0, -35.0, -28.0];
    s[(k / 15 + k * 7 / 11) % s.len()]
}

/// The room: the robot's voice played at frame `k` reaches the microphone `delay` frames
/// later, `gain` dB louder, over a -70 dBFS floor; the canceller's output is the
/// microphone's minus `erle` dB of the robot, and the player (levels by frame) as they are.
struct Room {
    d: DoubleTalk,
    delay: usize,
    gain: f64,
    played: Vec<f64>,
    /// How much the canceller takes out of the player too (its suppressor, while the robot
    /// speaks; dB).
    player_loss_db: f64,
    /// The microphone's levels, frame by frame.
    heard: Vec<f64>,
    /// Frames the microphone's stream does not deliver (lost on the way).
    mic_lost: std::ops::Range<usize>,
    /// How much the canceller takes out of the room's noise while the robot speaks (dB).
    floor_loss_db: f64,
    /// How far the room's noise through the canceller dips in one frame of ten (dB): a
    /// suppressor releasing, a noise suppressor's swings.
    room_dip_db: f64,
}

impl Room {
    fn new(delay: usize, gain: f64) -> Self {
        Room {
            d: DoubleTalk::new(Config::default()),
            delay,
            gain,
            played: Vec::new(),
            player_loss_db: 0.0,
            heard: Vec::new(),
            mic_lost: 0..0,
            floor_loss_db: 0.0,
            room_dip_db: 0.0,
        }
    }

    /// `n` frames: the robot says `robot(k)` (None: silent), the player `player(k)`; the
    /// canceller takes `erle` dB out of the robot. The outcome and the output's levels.
    fn run(
        &mut self,
        n: usize,
        robot: impl Fn(usize) -> Option<f64>,
        player: impl Fn(usize) -> Option<f64>,
        erle: f64,
    ) -> (Outcome, Vec<f64>) {
        let mut sum = Outcome::default();
        let mut levels = Vec::new();
        for _ in 0..n {
            let k = self.played.len();
            let t = k as i64 * FRAME_NS;
            let r = robot(k).unwrap_or(SILENCE_DB);
            self.played.push(r);
            if robot(k).is_some() {
                self.d.reference(t, RATE, &frame_at(r, k));
            }
            let echo = k
                .checked_sub(self.delay)
                .map_or(SILENCE_DB, |j| self.played[j] + self.gain);
            let p = player(k).unwrap_or(SILENCE_DB);
            let sum_db = |a: f64, b: f64, c: f64| {
                10.0 * (10f64.powf(a / 10.0) + 10f64.powf(b / 10.0) + 10f64.powf(c / 10.0)).log10()
            };
            let mic = sum_db(echo, p, -70.0);
            let room = if echo > SILENCE_DB {
                -75.0 - self.floor_loss_db
            } else if k.is_multiple_of(10) {
                -75.0 - self.room_dip_db
            } else {
                -75.0
            };
            let out = sum_db(echo - erle, p - self.player_loss_db, room);
            self.heard.push(mic);
            if !self.mic_lost.contains(&k) {
                self.d.mic(t, RATE, &frame_at(mic, k));
            }
            let mut o = frame_at(out, k);
            self.d.canceller(t, RATE, &o);
            let oc = self.d.process(t, RATE, &mut o);
            sum.robot_frames += oc.robot_frames;
            sum.player_frames += oc.player_frames;
            sum.suppressed_frames += oc.suppressed_frames;
            sum.unheld_frames += oc.unheld_frames;
            levels.push(level_db(&o));
        }
        (sum, levels)
    }
}

#[test]
fn without_the_robot_everything_passes() {
    let mut room = Room::new(12, -3.0);
    let (o, levels) = room.run(100, |_| None, |k| Some(voice(k)), 0.0);
    assert_eq!(o, Outcome::default());
    assert!(levels.iter().all(|&l| l > -50.0), "{levels:?}");
}

#[test]
fn the_echo_path_is_measured_and_the_robots_leaks_are_cut() {
    let mut room = Room::new(12, -3.0);
    // The robot's first words: the path is not known yet, everything is cut.
    let (o, levels) = room.run(80, |k| Some(voice(k)), |_| None, 5.0);
    assert_eq!(o.player_frames, 0, "{o:?}");
    assert!(levels[20..].iter().all(|&l| l < -65.0), "{levels:?}");
    // A second of speech: measured, 12 frames and -3 dB.
    room.run(40, |k| Some(voice(k)), |_| None, 5.0);
    let p = room.d.path().expect("the echo path");
    assert_eq!(p.delay_frames, 12, "{p:?}");
    assert!((p.gain_db + 3.0).abs() < 0.5, "{p:?}");
    // A room without reverberation: the fastest decay, the least margin.
    assert_eq!(p.decay_db_per_s, 400.0, "{p:?}");
    assert_eq!(p.margin_db, 4.0, "{p:?}");
    assert!(room.d.path_changed().is_some());
    // The canceller lets 25 dB through (a burst as loud as a player's voice): still cut.
    let (o, levels) = room.run(100, |k| Some(voice(k)), |_| None, 0.0);
    assert_eq!(o.player_frames, 0, "{o:?}");
    assert!(levels.iter().all(|&l| l < -65.0), "{levels:?}");
}

/// While the robot's voice is cut, the output is the room's own floor, steady, however far
/// the canceller takes the room's noise down with the robot's voice and whatever it lets
/// through: the recognizer's end-pointer must hear a quiet room, not talk.
#[test]
fn what_is_cut_of_the_robot_stands_steady_at_the_rooms_level() {
    let mut room = Room::new(12, -3.0);
    room.floor_loss_db = 30.0;
    // The room alone, through the canceller (-75 dBFS, as frames make it).
    let (_, levels) = room.run(50, |_| None, |_| None, 0.0);
    let floor = levels[49];
    assert!((floor + 75.0).abs() < 2.0, "{levels:?}");
    // Three seconds of the robot, then the room alone again.
    let cut = robot_speaks(&mut room, 30);
    assert_steady(&cut, floor, 1.5);
    let (_, after) = room.run(100, |_| None, |_| None, 40.0);
    assert!(after.iter().all(|&l| (l - floor).abs() < 1.5), "{after:?}");
}

/// Where the room's noise through the canceller dips now and then, what is cut of the robot
/// stands at the room's usual level, not at its dips: a step down when the robot starts
/// speaking is talk to the recognizer's end-pointer.
#[test]
fn what_is_cut_of_the_robot_stands_at_the_rooms_level_not_its_dips() {
    let mut room = Room::new(12, -3.0);
    room.room_dip_db = 15.0;
    room.floor_loss_db = 30.0;
    let (_, mut before) = room.run(300, |_| None, |_| None, 0.0);
    before.sort_by(f64::total_cmp);
    // -75 dBFS as frames make it (-76.3), the dips at -90.
    let usual = before[before.len() / 2];
    // Within 3 dB of the room's usual level, its dips 15 dB under it.
    let cut = robot_speaks(&mut room, 20);
    assert_steady(&cut, usual, 3.0);
}

/// The robot speaks `chunks` times 10 frames, the canceller taking 20 to 60 dB out of its
/// voice (and `floor_loss_db` out of the room) and the detector hearing no player: the
/// output's levels.
fn robot_speaks(room: &mut Room, chunks: i32) -> Vec<f64> {
    let mut cut = Vec::new();
    for i in 0..chunks {
        let erle = 20.0 + f64::from(i * 17 % 41);
        let (o, levels) = room.run(10, |k| Some(voice(k)), |_| None, erle);
        assert_eq!(o.player_frames, 0, "{o:?}");
        cut.extend(levels);
    }
    cut
}

/// Every level from the echo's arrival (12 frames) on within `tolerance_db` of `level`.
fn assert_steady(levels: &[f64], level: f64, tolerance_db: f64) {
    let off: Vec<f64> = levels[12..]
        .iter()
        .copied()
        .filter(|l| (l - level).abs() > tolerance_db)
        .collect();
    assert!(
        off.is_empty(),
        "frames off the room's level ({level:.1}): {off:?}"
    );
}

#[test]
fn the_player_over_the_robot_passes_and_the_robots_tail_is_cut_after() {
    let mut room = Room::new(12, -3.0);
    room.run(200, |k| Some(voice(k)), |_| None, 20.0);
    assert!(room.d.path().is_some());
    // The player says something as loud as the robot, over it, for half a second.
    assert!(!room.d.player_started());
    let (o, levels) = room.run(50, |k| Some(voice(k)), |k| Some(voice(k + 5) + 3.0), 20.0);
    assert!(room.d.player_started());
    assert!(o.player_frames >= 40, "{o:?}");
    assert!(levels[10..].iter().all(|&l| l > -50.0), "{levels:?}");
    // The robot alone again: held for 0.3 s after the player's last loud frame, then cut.
    let (o, _) = room.run(60, |k| Some(voice(k)), |_| None, 20.0);
    assert!((15..=30).contains(&o.player_frames), "{o:?}");
    assert!(o.suppressed_frames >= 28, "{o:?}");
}

/// The player as loud at the microphone as the robot's echo: the microphone alone does not
/// tell her apart, but the canceller's output stands far over what it leaves of the robot.
#[test]
fn the_player_as_loud_as_the_robot_shows_in_the_cancellers_output() {
    let mut room = Room::new(12, -3.0);
    // The microphone alone never tells her apart here.
    room.d.cfg.margin_db = (40.0, 40.0);
    room.run(400, |k| Some(voice(k)), |_| None, 25.0);
    assert!(room.d.path().is_some());
    // A leak: the canceller lets 13 dB more of the robot through, far over what it left
    // lately, but 12 dB under the microphone: the robot still.
    let (o, _) = room.run(30, |k| Some(voice(k)), |_| None, 12.0);
    assert!(!room.d.player_started(), "{o:?}");
    assert_eq!(o.player_frames, 0, "{o:?}");
    let (o, levels) = room.run(
        50,
        |k| Some(voice(k)),
        |k| Some(voice(k + 12 - 4) - 3.0),
        25.0,
    );
    assert!(room.d.player_started());
    assert!(o.player_frames >= 40, "{o:?}");
    assert!(levels[10..].iter().all(|&l| l > -50.0), "{levels:?}");
}

/// While the robot speaks, the canceller takes 30 dB out of the player too (and 45 out of
/// the robot): the frames passed as hers are the microphone's, not the canceller's.
#[test]
fn the_players_frames_are_the_microphone_as_it_is() {
    let mut room = Room::new(12, -3.0);
    room.player_loss_db = 30.0;
    room.run(200, |k| Some(voice(k)), |_| None, 45.0);
    let (o, levels) = room.run(50, |k| Some(voice(k)), |k| Some(voice(k + 5) + 6.0), 45.0);
    assert!(o.player_frames >= 40, "{o:?}");
    assert_eq!(o.unheld_frames, 0, "{o:?}");
    let heard = &room.heard[room.heard.len() - 50..];
    for (k, (&out, &mic)) in levels.iter().zip(heard).enumerate().skip(10) {
        assert!(
            (out - mic).abs() < 0.5,
            "frame {k}: {out:.1} dBFS out, {mic:.1} heard"
        );
    }
}

/// A busy machine's timing: the robot's voice reaches the microphone 80 ms later than the
/// echo path measured says, so the end of its word stands over the echo predicted for it,
/// as a player would. The canceller (on the sound server's clock) took the word out as
/// ever: without its word, the microphone alone takes the robot for her.
#[test]
fn the_robot_heard_late_on_the_microphone_is_not_the_player() {
    let word = |k: usize| (k % 40 < 15).then_some(-20.0);
    for confirm in [None, Some(10.0)] {
        let mut room = Room::new(12, -3.0);
        room.d.cfg.confirm_db = confirm;
        room.run(200, |k| Some(voice(k)), |_| None, 45.0);
        assert_eq!(room.d.path().map(|p| p.delay_frames), Some(12));
        room.delay = 20;
        let (o, _) = room.run(40, word, |_| None, 45.0);
        match confirm {
            None => assert!(room.d.player_started(), "the scenario: {o:?}"),
            Some(_) => {
                assert!(!room.d.player_started(), "{o:?}");
                assert_eq!(o.player_frames, 0, "{o:?}");
            }
        }
    }
}

/// The streams' timing puts the robot's voice on the microphone a few frames later than the
/// echo path measured (30 ms, within [`Config::jitter_frames`]): the ends of its words are
/// heard where the reference has fallen silent. They are its echo, not the player, even
/// without the canceller's confirmation.
#[test]
fn the_robot_heard_a_few_frames_late_is_its_echo() {
    let word = |k: usize| (k % 40 < 15).then_some(-20.0);
    let mut room = Room::new(12, -3.0);
    room.d.cfg.confirm_db = None;
    room.run(200, |k| Some(voice(k)), |_| None, 45.0);
    assert_eq!(room.d.path().map(|p| p.delay_frames), Some(12));
    room.delay = 15;
    let (o, _) = room.run(120, word, |_| None, 45.0);
    assert!(!room.d.player_started(), "{o:?}");
    assert_eq!(o.player_frames, 0, "{o:?}");
}

/// Five frames of the microphone's stream lost while she speaks: those frames pass as the
/// canceller left them, and are counted; the next ones are the microphone's again.
#[test]
fn the_players_frames_the_microphone_lost_are_counted() {
    let mut room = Room::new(12, -3.0);
    room.player_loss_db = 30.0;
    room.run(200, |k| Some(voice(k)), |_| None, 45.0);
    room.mic_lost = 230..235;
    let (o, levels) = room.run(50, |k| Some(voice(k)), |k| Some(voice(k + 5) + 6.0), 45.0);
    assert!(o.player_frames >= 40, "{o:?}");
    assert_eq!(o.unheld_frames, 5, "{o:?}");
    let heard = &room.heard[200..];
    for k in (10..50).filter(|k| !(30..35).contains(k)) {
        assert!((levels[k] - heard[k]).abs() < 0.5, "frame {k}");
    }
    // The canceller's output: 30 dB under her.
    assert!(levels[32] < heard[32] - 20.0, "{levels:?}");
}

#[test]
fn the_microphones_tail_is_contiguous_and_starts_again_after_a_jump() {
    let mut tail = Tail::default();
    let ms = 1_000_000;
    let chunk: Vec<i16> = (0..320).collect();
    tail.push(0, RATE, &chunk, 1_000 * ms);
    // 1 ms late by the stream's latency estimate: still the next samples.
    let next: Vec<i16> = (320..640).collect();
    tail.push(21 * ms, RATE, &next, 1_000 * ms);
    let mut out = [0i16; 160];
    assert!(tail.copy(30 * ms, RATE, &mut out));
    assert_eq!(out[0], 480);
    // Not held: before the first, past the last, another rate.
    assert!(!tail.copy(-ms, RATE, &mut out));
    assert!(!tail.copy(35 * ms, RATE, &mut out));
    assert!(!tail.copy(0, 48_000, &mut out));
    // A jump of 100 ms: what was held is no longer next to it.
    tail.push(140 * ms, RATE, &chunk, 1_000 * ms);
    assert!(!tail.copy(30 * ms, RATE, &mut out));
    assert!(tail.copy(140 * ms, RATE, &mut out));
    assert_eq!(out[0], 0);
    // Only the last `keep_ns` are kept.
    for c in 0..10 {
        tail.push((160 + 20 * c) * ms, RATE, &chunk, 50 * ms);
    }
    assert!(!tail.copy(200 * ms, RATE, &mut out));
    assert!(tail.copy(320 * ms, RATE, &mut out));
}

#[test]
fn a_pause_drops_what_was_queued_and_the_robot_ends_after_its_tail() {
    let mut room = Room::new(12, -3.0);
    room.run(200, |k| Some(voice(k)), |_| None, 20.0);
    // The robot falls silent: its echo and tail (12 + 30 frames) later, nothing is cut.
    let (o, _) = room.run(80, |_| None, |_| None, 20.0);
    assert!((40..=44).contains(&o.robot_frames), "{o:?}");
    // Queued audio thrown away before it played is no echo.
    room.d
        .reference(300 * FRAME_NS, RATE, &frame_at(-20.0, 0).repeat(50));
    room.d.reference_dropped_from(290 * FRAME_NS);
    assert!(!room.d.robot_at(400));
}

/// The microphone's stream starts in digital silence; the robot then speaks over a room
/// that the microphone hears at -52 dBFS, falls silent, and writes its next sentence ahead
/// of playing it, starting with the silence the speaker is primed with: meanwhile the
/// microphone hears the room alone, which is no player (the floor is the room's, not the
/// silence's).
#[test]
fn a_room_heard_after_digital_silence_is_no_player() {
    let mut d = DoubleTalk::new(Config::default());
    let t = |k: usize| k as i64 * FRAME_NS;
    for k in 0..200 {
        d.mic(t(k), RATE, &[0; FRAME]);
    }
    for k in 200..350 {
        d.reference(t(k), RATE, &frame_at(voice(k), k));
        d.mic(t(k), RATE, &frame_at(voice(k).max(-52.0), k));
    }
    assert!(d.path().is_some());
    for k in 350..400 {
        d.mic(t(k), RATE, &frame_at(-52.0, k));
    }
    assert!(!d.player_started());
    // The next sentence, written 200 ms ahead: 20 frames of silence, then the voice.
    d.reference(t(400), RATE, &[0; FRAME * 20]);
    let ahead: Vec<i16> = (420..470).flat_map(|k| frame_at(voice(k), k)).collect();
    d.reference(t(420), RATE, &ahead);
    for k in 400..420 {
        d.mic(t(k), RATE, &frame_at(-52.0, k));
    }
    assert!(!d.player_started());
}

#[test]
fn levels_of_silence_and_full_scale() {
    assert_eq!(level_db(&[0; 160]), SILENCE_DB);
    assert_eq!(level_db(&[]), SILENCE_DB);
    assert!(level_db(&[i16::MIN; 160]).abs() < 1e-9);
}

#[test]
fn correlation_of_lines() {
    let up: Vec<(f64, f64)> = (0..10).map(|i| (i as f64, 2.0 * i as f64)).collect();
    assert!((correlation(&up) - 1.0).abs() < 1e-9);
    let flat: Vec<(f64, f64)> = (0..10).map(|i| (i as f64, 3.0)).collect();
    assert_eq!(correlation(&flat), 0.0);
}
