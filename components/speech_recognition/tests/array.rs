#![allow(clippy::unwrap_used)]
//! Files in, commands out through a microphone array (`--wav FILE --array NAME`): the player's
//! commands and two other people talking from elsewhere in the room, as a 4-microphone circular
//! array hears them (plane waves, no room), beamformed and decoded as the component does.

mod common;

use audio::array::{ArrayGeometry, sim::TalkersRoom};
use audio::wav::Pcm;
use common::voice;
use interfaces::msg::command::{Command, Game};
use speech_recognition::array_wav::{ArrayWavError, Beamformed, beamform};
use speech_recognition::{Recognized, Recognizer, RecognizerConfig};

const RATE: usize = 16_000;

/// A room as the array hears it: the touch game's commands from the player at `player_deg`,
/// 2 s apart after 6 s of the others' talk, and two other people talking all along from
/// `others_deg`, each `under_db` under the player. Returns the recording and where each command
/// starts (samples).
fn room(
    geometry: &ArrayGeometry,
    player_deg: f64,
    others_deg: [f64; 2],
    under_db: f64,
) -> (Pcm, Vec<Command>, Vec<usize>) {
    let commands: Vec<Command> = Command::of_game(Game::Touch).collect();
    let phrases: Vec<&str> = commands.iter().map(|c| c.phrase()).collect();
    let sentences = vec![
        "the bakery on the corner opens at seven every morning",
        "we drove along the coast and stopped for lunch in a small village",
        "he keeps his old records in a box under the stairs",
        "the garden looks lovely after the rain in spring",
    ];
    let rendered = TalkersRoom {
        player: voice("en-gb", 150, 45),
        phrases: &phrases,
        player_azimuth_rad: player_deg.to_radians(),
        others: vec![
            (
                voice("en-us+m2", 160, 40),
                others_deg[0].to_radians(),
                sentences.clone(),
            ),
            (
                voice("en-gb+f5", 170, 40),
                others_deg[1].to_radians(),
                sentences,
            ),
        ],
        under_db,
        lead_s: 6.0,
        gap_s: 2.0,
        mic_noise: 30.0,
        seed: 3,
        reverb: None,
    }
    .render(geometry)
    .unwrap();
    (rendered.pcm, commands, rendered.starts)
}

fn decode(samples: &[i16]) -> Vec<Recognized> {
    let mut rec = Recognizer::shipped(Game::Touch, RecognizerConfig::default()).unwrap();
    let mut got = vec![];
    for chunk in samples.chunks(320) {
        got.extend(rec.push(chunk).unwrap());
    }
    got.extend(rec.flush().unwrap());
    got
}

/// What the component hears of a beamformed recording: each block judged hers or not.
fn decode_heard(b: &Beamformed) -> Vec<Recognized> {
    let mut rec = Recognizer::shipped(Game::Touch, RecognizerConfig::default()).unwrap();
    speech_recognition::array_wav::decode(&mut rec, &b.heard).unwrap()
}

/// How many commands were heard as exactly themselves between their start and the next one's.
fn right(got: &[Recognized], commands: &[Command], starts: &[usize]) -> usize {
    commands
        .iter()
        .zip(starts)
        .enumerate()
        .filter(|&(i, (c, &at))| {
            let from = at as f64 / RATE as f64;
            let to = starts
                .get(i + 1)
                .map_or(f64::MAX, |&n| n as f64 / RATE as f64);
            let heard: Vec<Command> = got
                .iter()
                .filter(|r| r.start_s >= from - 0.2 && r.start_s < to - 0.2)
                .filter(|r| r.command != Command::None)
                .map(|r| r.command)
                .collect();
            heard == [*c]
        })
        .count()
}

/// Two people talk 6 dB under the player, 75 and 120 degrees away from her. The localizer
/// finds her; the beam steered at her hears more of her commands than one microphone of the
/// same array; the talk alone never gives a command; and steered at one of the others, the beam
/// hears fewer of hers.
#[test]
fn the_beam_finds_the_player_and_hears_her_over_two_other_talkers() {
    let g = ArrayGeometry::builtin("circular_6").unwrap();
    let (pcm, commands, starts) = room(&g, 20.0, [95.0, -100.0], 6.0);
    let b = beamform(&pcm, &g, None).unwrap();
    assert!(b.located);
    let off = (b.azimuth_rad.to_degrees() - 20.0).abs();
    assert!(
        off < 10.0,
        "listening at {:.1} degrees",
        b.azimuth_rad.to_degrees()
    );
    let got = decode_heard(&b);
    let lead_s = starts[0] as f64 / RATE as f64 - 0.2;
    assert!(
        got.iter()
            .all(|r| r.start_s >= lead_s || r.command == Command::None),
        "the talk alone gave a command: {got:#?}"
    );
    let beam_right = right(&got, &commands, &starts);
    let ungated_right = right(&decode(&b.samples()), &commands, &starts);
    let one: Vec<i16> = pcm.samples.iter().step_by(g.channels()).copied().collect();
    let mic_right = right(&decode(&one), &commands, &starts);
    let away = beamform(&pcm, &g, Some(95f64.to_radians())).unwrap();
    assert!(!away.located);
    let away_right = right(&decode(&away.samples()), &commands, &starts);
    let (elsewhere, blocks) = b.elsewhere();
    eprintln!(
        "{} commands right: {beam_right} through the beam at {:.1} degrees with its end-pointer \
         told what came from elsewhere ({elsewhere} of {blocks} blocks), {ungated_right} through \
         the beam alone, {mic_right} through one microphone, {away_right} through the beam \
         steered at another talker",
        commands.len(),
        b.azimuth_rad.to_degrees()
    );
    assert!(beam_right > mic_right, "{beam_right} against {mic_right}");
    assert!(
        beam_right >= ungated_right,
        "{beam_right} against {ungated_right}"
    );
    assert!(away_right < beam_right, "{away_right} against {beam_right}");
}

/// A recording whose channels do not match the array, a silent one, or an azimuth that is not a
/// number: a clear error, never a panic.
#[test]
fn a_recording_that_does_not_fit_the_array_is_a_clear_error() {
    let g = ArrayGeometry::builtin("kinect_v1").unwrap();
    let three = Pcm {
        sample_rate_hz: 16_000,
        channels: 3,
        samples: vec![0; 3 * 16_000],
    };
    let e = beamform(&three, &g, None).unwrap_err().to_string();
    assert!(e.contains('3') && e.contains('4'), "{e}");
    let silent = Pcm {
        sample_rate_hz: 16_000,
        channels: 4,
        samples: vec![0; 4 * 16_000],
    };
    assert!(matches!(
        beamform(&silent, &g, None),
        Err(ArrayWavError::NoTalker)
    ));
    assert!(matches!(
        beamform(&silent, &g, Some(f64::NAN)),
        Err(ArrayWavError::BadAzimuth(_))
    ));
    // A recording at 48 kHz is resampled to the array's rate.
    let fast = Pcm {
        sample_rate_hz: 48_000,
        channels: 4,
        samples: vec![0; 4 * 48_000],
    };
    let b = beamform(&fast, &g, Some(0.0)).unwrap();
    assert_eq!(b.sample_rate_hz, 16_000);
    assert!(
        b.samples().len().abs_diff(16_000) <= 1,
        "{}",
        b.samples().len()
    );
}
