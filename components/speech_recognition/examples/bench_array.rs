#![allow(clippy::unwrap_used)]
#![expect(
    clippy::disallowed_methods,
    reason = "a benchmark: it measures the hearing chain's compute time on the wall"
)]
//! Hearing through a microphone array, against one microphone of the same array (the peer): the
//! player says every command of a game, 2 s apart, from where the robot knows she stands, while
//! two other people talk all along from elsewhere in the room (at least 45 degrees away from
//! her), each 10 dB under her as they speak; a 4-microphone circular array hears the room. The
//! conditions:
//!
//! - `two_talkers_10db`: every talker a plane wave (far, in free field: no reverberation);
//! - `clean`: the same rooms with nobody else talking, to show what the chain costs when there
//!   is nothing to take out;
//! - `two_talkers_10db_rt60_0.5` and `clean_rt60_0.5`: the same in a reverberant room (image
//!   sources), 6 x 5 x 3 m with an RT60 of 0.5 s, the array at (2.5, 2.5, 1.2) m facing the
//!   room's x axis, every talker 1.5 m from it at its height (about twice the room's critical
//!   distance, so her reflections carry several times her direct sound's energy); all the
//!   talkers are scaled by one gain that brings her speech to the array at its level as spoken.
//!
//! The chains, on the same recording, each a live stream in `audio_io`'s 20 ms chunks:
//!
//! - `beam`: the component's chain (`speech_recognition --array circular_4
//!   --target-azimuth-deg <hers>`): delay-and-sum steered at her, the end-pointer told which
//!   100 ms blocks the localizer places elsewhere;
//! - `beam_ungated`: the same beam, the end-pointer told nothing;
//! - `one_mic` (the peer): the array's first microphone alone.
//!
//! Evaluation voices only: the player is one of flite's voices (another synthesizer family,
//! built from recordings of real speakers, never used to adapt or tune anything); the others are
//! espeak-ng's evaluation voices saying the evaluation set's background sentences.
//!
//! Figures per chain and condition: commands heard right (exactly that command, once, in its
//! window), right and carried out at once (confidence at or above the dialog's high threshold,
//! 0.7), commands wrongly carried out (a sure command nobody gave: a wrong one in a command's
//! window, or one made of the others' talk, per command said), and the chain's real-time factor.
//! The last line printed is a JSON summary (`<condition>_<chain>_right_pct` and so on, and
//! `ratio_<condition>_beam_right_vs_one_mic`). `--voices slt,rms`, `--games touch` and
//! `--conditions clean,clean_rt60_0.5` narrow it; `--write-wav DIR` also writes each room's
//! recording (`<game>_<voice>_<condition>.wav`), for `speech_recognition --wav FILE --array
//! circular_4 --target-azimuth-deg <hers>`.

use audio::array::ArrayGeometry;
use audio::array::room::ShoeboxRoom;
use audio::array::sim::{RenderedRoom, Reverb, TalkersRoom};
use audio::synth::Voice;
use interfaces::msg::command::{Command, Game};
use speech_recognition::beam::LiveBeam;
use speech_recognition::{Recognized, Recognizer, RecognizerConfig};

mod corpus;
use corpus::{EVAL_BABBLE, EVAL_VOICES};

/// The dialog's high threshold: a command at or above it is carried out at once.
const HIGH: f64 = 0.7;
/// audio_io's chunks (20 ms), per channel.
const CHUNK: usize = 320;
const RATE: f64 = 16_000.0;
/// The player's voices: flite's, at 16 kHz.
const PLAYERS: [&str; 4] = ["slt", "rms", "awb", "kal16"];
/// Where the player stands (degrees, the array's frame), voice by voice; the others stand 100
/// degrees to her left and 135 to her right.
const PLAYER_DEG: [f64; 4] = [0.0, 35.0, -40.0, 70.0];
const OTHERS_DEG: [f64; 2] = [100.0, -135.0];
const UNDER_DB: f64 = 10.0;
const LEAD_S: f64 = 4.0;
const GAP_S: f64 = 2.0;
/// The reverberant room: its size (m), its reverberation time (s), where the array stands in
/// it (m) and how far from it every talker stands (m).
const ROOM_DIMS_M: [f64; 3] = [6.0, 5.0, 3.0];
const ROOM_RT60_S: f64 = 0.5;
const ROOM_ARRAY_M: [f64; 3] = [2.5, 2.5, 1.2];
const ROOM_DISTANCE_M: f64 = 1.5;

/// A kind of room the benchmark renders for every game and voice (see the module doc).
#[derive(Clone, Copy)]
struct Condition {
    name: &'static str,
    /// Whether the two others talk.
    others: bool,
    /// Whether in the reverberant room, rather than plane waves in free field.
    reverberant: bool,
}

/// The plane-wave conditions first, under the names they have always had, so that earlier
/// figures stay comparable.
const CONDITIONS: [Condition; 4] = [
    Condition {
        name: "clean",
        others: false,
        reverberant: false,
    },
    Condition {
        name: "two_talkers_10db",
        others: true,
        reverberant: false,
    },
    Condition {
        name: "clean_rt60_0.5",
        others: false,
        reverberant: true,
    },
    Condition {
        name: "two_talkers_10db_rt60_0.5",
        others: true,
        reverberant: true,
    },
];

#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Debug)]
enum Chain {
    Beam,
    BeamUngated,
    OneMic,
}

impl Chain {
    const ALL: [Chain; 3] = [Chain::Beam, Chain::BeamUngated, Chain::OneMic];
    fn name(self) -> &'static str {
        match self {
            Chain::Beam => "beam",
            Chain::BeamUngated => "beam_ungated",
            Chain::OneMic => "one_mic",
        }
    }
}

#[derive(Default, Clone, Copy)]
struct Tally {
    said: usize,
    right: usize,
    at_once: usize,
    wrong_at_once: usize,
    audio_s: f64,
    compute_s: f64,
}

/// What `chain` hears of `room`, as a live stream, and the compute it took (s).
fn hear(
    chain: Chain,
    room: &RenderedRoom,
    geometry: &ArrayGeometry,
    azimuth_rad: f64,
    game: Game,
) -> (Vec<Recognized>, f64) {
    let mut rec = Recognizer::shipped(game, RecognizerConfig::default()).unwrap();
    let channels = geometry.channels();
    let mut beam = LiveBeam::new(geometry, azimuth_rad).unwrap();
    let mut got = Vec::new();
    let t = std::time::Instant::now();
    for chunk in room.pcm.samples.chunks(CHUNK * channels) {
        match chain {
            Chain::OneMic => {
                let one: Vec<i16> = chunk.iter().step_by(channels).copied().collect();
                got.extend(rec.push(&one).unwrap());
            }
            Chain::Beam | Chain::BeamUngated => {
                for h in beam.push(chunk, channels, 0) {
                    let elsewhere = chain == Chain::Beam && h.elsewhere;
                    got.extend(rec.push_from(&h.samples, elsewhere).unwrap());
                }
            }
        }
    }
    if chain != Chain::OneMic
        && let Some(h) = beam.finish()
    {
        got.extend(
            rec.push_from(&h.samples, chain == Chain::Beam && h.elsewhere)
                .unwrap(),
        );
    }
    got.extend(rec.flush().unwrap());
    (got, t.elapsed().as_secs_f64())
}

/// Scores what was heard against what was said (see the module doc).
fn score(t: &mut Tally, got: &[Recognized], said: &[Command], starts: &[usize], beam_late_s: f64) {
    let window = |i: usize| {
        let from = starts[i] as f64 / RATE - 0.2 + beam_late_s;
        let to = starts
            .get(i + 1)
            .map_or(f64::MAX, |&n| n as f64 / RATE - 0.2 + beam_late_s);
        (from, to)
    };
    for (i, c) in said.iter().enumerate() {
        let (from, to) = window(i);
        let heard: Vec<&Recognized> = got
            .iter()
            .filter(|r| r.start_s >= from && r.start_s < to && r.command != Command::None)
            .collect();
        t.said += 1;
        if heard.len() == 1 && heard[0].command == *c {
            t.right += 1;
            if heard[0].confidence >= HIGH {
                t.at_once += 1;
            }
        }
        t.wrong_at_once += heard
            .iter()
            .filter(|r| r.command != *c && r.confidence >= HIGH)
            .count();
    }
    // Before her first command, only the others talk.
    let (first, _) = window(0);
    t.wrong_at_once += got
        .iter()
        .filter(|r| r.start_s < first && r.command != Command::None && r.confidence >= HIGH)
        .count();
}

fn pct(a: usize, b: usize) -> f64 {
    if b == 0 {
        f64::NAN
    } else {
        100.0 * a as f64 / b as f64
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let list = |flag: &str| -> Option<Vec<String>> {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1))
            .map(|v| v.split(',').map(str::to_string).collect())
    };
    let players: Vec<String> =
        list("--voices").unwrap_or_else(|| PLAYERS.iter().map(|s| s.to_string()).collect());
    let games: Vec<Game> = list("--games")
        .unwrap_or_else(|| vec!["touch".into(), "coach".into()])
        .iter()
        .map(|g| Game::from_name(g).unwrap_or_else(|| panic!("unknown game {g:?}")))
        .collect();
    let conditions: Vec<Condition> = match list("--conditions") {
        None => CONDITIONS.to_vec(),
        Some(names) => {
            for n in &names {
                if !CONDITIONS.iter().any(|c| c.name == n) {
                    let known: Vec<&str> = CONDITIONS.iter().map(|c| c.name).collect();
                    panic!("unknown condition {n:?} (known: {})", known.join(", "));
                }
            }
            CONDITIONS
                .into_iter()
                .filter(|c| names.iter().any(|n| n == c.name))
                .collect()
        }
    };
    let reverb = Reverb {
        room: ShoeboxRoom::for_rt60(ROOM_DIMS_M, ROOM_RT60_S).unwrap(),
        array_m: ROOM_ARRAY_M,
        yaw_rad: 0.0,
        distance_m: ROOM_DISTANCE_M,
    };
    let write_wav = list("--write-wav").map(|v| v.join(","));
    if let Some(dir) = &write_wav {
        std::fs::create_dir_all(dir).unwrap();
    }
    let geometry = ArrayGeometry::builtin("circular_4").unwrap();
    let beam_late_s = LiveBeam::new(&geometry, 0.0).unwrap().latency_ns() as f64 / 1e9;
    let mut tallies: std::collections::BTreeMap<(&str, Chain), Tally> = Default::default();
    println!(
        "array {} ({} microphones); player: flite voices {}; two others at +{}/{} degrees from the array, {UNDER_DB} dB under her",
        geometry.name(),
        geometry.channels(),
        players.join(", "),
        OTHERS_DEG[0],
        OTHERS_DEG[1]
    );
    println!(
        "reverberant room: {ROOM_DIMS_M:?} m, RT60 {ROOM_RT60_S} s, the array at {ROOM_ARRAY_M:?} m, the talkers {ROOM_DISTANCE_M} m from it"
    );
    for game in &games {
        let said: Vec<Command> = Command::of_game(*game).collect();
        let phrases: Vec<&str> = said.iter().map(|c| c.phrase()).collect();
        for (vi, p) in players.iter().enumerate() {
            let player_deg = PLAYER_DEG[vi % PLAYER_DEG.len()];
            for c in &conditions {
                let condition = c.name;
                let others = if c.others {
                    OTHERS_DEG
                        .iter()
                        .enumerate()
                        .map(|(k, deg)| {
                            let v = Voice {
                                voice: EVAL_VOICES[(vi + k) % EVAL_VOICES.len()].into(),
                                speed_wpm: 165,
                                pitch: 40 + 10 * k as u8,
                            };
                            let sentences: Vec<&str> =
                                EVAL_BABBLE.iter().skip(3 * k).copied().collect();
                            (v, deg.to_radians(), sentences)
                        })
                        .collect()
                } else {
                    vec![]
                };
                let room = TalkersRoom {
                    player: Voice {
                        voice: format!("flite:{p}"),
                        speed_wpm: 175,
                        pitch: 50,
                    },
                    phrases: &phrases,
                    player_azimuth_rad: player_deg.to_radians(),
                    others,
                    under_db: UNDER_DB,
                    lead_s: LEAD_S,
                    gap_s: GAP_S,
                    mic_noise: 30.0,
                    seed: 100 + vi as u64,
                    reverb: c.reverberant.then_some(reverb),
                }
                .render(&geometry)
                .unwrap();
                if let Some(dir) = &write_wav {
                    let file = format!("{dir}/{}_{p}_{condition}.wav", game.name());
                    std::fs::write(&file, audio::wav::encode(&room.pcm)).unwrap();
                }
                let audio_s = room.pcm.samples.len() as f64 / geometry.channels() as f64 / RATE;
                for chain in Chain::ALL {
                    let (got, compute_s) =
                        hear(chain, &room, &geometry, player_deg.to_radians(), *game);
                    let late = if chain == Chain::OneMic {
                        0.0
                    } else {
                        beam_late_s
                    };
                    let t = tallies.entry((condition, chain)).or_default();
                    let before = *t;
                    score(t, &got, &said, &room.starts, late);
                    t.audio_s += audio_s;
                    t.compute_s += compute_s;
                    eprintln!(
                        "{:5} {p:6} at {player_deg:+4.0} deg {condition:25} {:12}: {}/{} right, {} at once, {} wrongly at once",
                        game.name(),
                        chain.name(),
                        t.right - before.right,
                        said.len(),
                        t.at_once - before.at_once,
                        t.wrong_at_once - before.wrong_at_once
                    );
                }
            }
        }
    }
    println!(
        "\n{:25} {:12} {:>8} {:>9} {:>10} {:>16} {:>6}",
        "condition", "chain", "said", "right %", "at once %", "wrong at once %", "RTF"
    );
    let mut json = serde_json::Map::new();
    for ((condition, chain), t) in &tallies {
        let rtf = t.compute_s / t.audio_s.max(1e-9);
        println!(
            "{condition:25} {:12} {:>8} {:>9.1} {:>10.1} {:>16.2} {:>6.3}",
            chain.name(),
            t.said,
            pct(t.right, t.said),
            pct(t.at_once, t.said),
            pct(t.wrong_at_once, t.said),
            rtf
        );
        let key = format!("{condition}_{}", chain.name());
        json.insert(format!("{key}_right_pct"), round(pct(t.right, t.said)));
        json.insert(format!("{key}_at_once_pct"), round(pct(t.at_once, t.said)));
        json.insert(
            format!("{key}_wrong_at_once_pct"),
            round(pct(t.wrong_at_once, t.said)),
        );
        json.insert(format!("{key}_rtf"), round(rtf));
    }
    for c in &conditions {
        let condition = c.name;
        let get = |chain| {
            tallies
                .get(&(condition, chain))
                .copied()
                .unwrap_or_default()
        };
        let (beam, peer) = (get(Chain::Beam), get(Chain::OneMic));
        if peer.right > 0 {
            json.insert(
                format!("ratio_{condition}_beam_right_vs_one_mic"),
                round(beam.right as f64 / peer.right as f64),
            );
        }
    }
    json.insert(
        "commands_said".into(),
        tallies.values().map(|t| t.said).max().unwrap_or(0).into(),
    );
    println!("{}", serde_json::Value::Object(json));
}

fn round(x: f64) -> serde_json::Value {
    serde_json::json!((x * 1000.0).round() / 1000.0)
}
