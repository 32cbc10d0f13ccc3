#![expect(
    clippy::disallowed_methods,
    reason = "a benchmark: it measures the audio path's latency through a real sound server on the wall"
)]
//! `scripts/bench audio`: the audio path through a sound server, as the robot uses it.
//!
//! - **Round trip, speaker to microphone**: a click sent on `audio/out` until it comes back on
//!   `audio/in`, through `audio_io`, the sound server's sink (the room), the virtual source on
//!   its monitor (the microphone) and `audio_io` again: two bus hops, the playback buffer and the
//!   capture chunk.
//! - **The peer (the floor)**: the same click written straight into the same sink with libpulse
//!   and read back from the same source, with the same buffering (the playback buffer filled with
//!   silence first, as `audio_io` does for the start of a sentence, and 20 ms capture chunks).
//!   The difference is what the bus and the component cost.
//! - **Capture to `audio/in`**: for every chunk, its arrival on the bus minus its stamp (the
//!   capture time of its first sample, as `audio_io` estimates it from the server's latency).
//!
//! - **The robot's own voice in its microphone**: sentences of the robot (espeak-ng, as the
//!   speech generator says them) played through `audio_io` on a loudspeaker heard in the room,
//!   with the microphone on the room, without an echo canceller (the peer: what gating must
//!   cover), with the sound server's WebRTC canceller alone (`--echo-cancel webrtc
//!   --residual-echo keep`), and with it and the double-talk detector (`--residual-echo
//!   suppress`). Measured:
//!   the robot's level in the room and on `audio/in` over the sentences, their difference (the
//!   echo return loss enhancement, ERLE), and the share of 10 ms frames of `audio/in` loud
//!   enough for the recognizer's end-pointer (-65 dBFS). The first sentence, while the
//!   canceller adapts, is reported apart.
//!
//! - **The player over the robot** (double talk): with the canceller alone (the peer) and with
//!   the detector, a player (another espeak-ng voice, on a sink of her own heard in the room)
//!   says six short commands, each one second into the robot's longest sentence; measured: the
//!   share of her voiced frames (within 30 dB of her peak) matched by frames of `audio/in`
//!   over the end-pointer's floor while she speaks. What the canceller alone passes is the
//!   most the detector can: it only ever takes out.
//!
//! The sound server is the caller's (`scripts/bench audio` starts one with a null sink `room`,
//! a virtual source `mic` on its monitor, and null sinks `speaker` and `person` heard in the
//! room through loop-backs). Prints tables, then one JSON line.

use audio_io::component::{self, Config, Driver, EchoCancel, ResidualEcho};
use clap::Parser;
use interfaces::msg::speech::AudioChunk;
use interfaces::node::Shutdown;
use interfaces::router::open_router;
use interfaces::{Bus, ConnectArgs, topics};
use std::sync::mpsc;
use std::time::{Duration, Instant};

#[derive(Debug, Clone, Parser)]
struct Args {
    /// The sound server (libpulse's address, e.g. unix:/path/native).
    #[arg(long)]
    server: String,
    /// The source that hears the sink.
    #[arg(long, default_value = "mic")]
    source: String,
    /// The sink standing for the room.
    #[arg(long, default_value = "room")]
    sink: String,
    /// Clicks per measurement.
    #[arg(long, default_value_t = 40)]
    clicks: usize,
    /// Clicks before measuring (the streams and the sink start).
    #[arg(long, default_value_t = 3)]
    warmup: usize,
    /// Time between two clicks (ms): the room is silent again before the next.
    #[arg(long, default_value_t = 500)]
    gap_ms: u64,
    /// The robot's loudspeaker for the echo measurement: a sink heard in the room.
    #[arg(long, default_value = "speaker")]
    echo_speaker: String,
    /// The microphone for the echo measurement (a source on the room).
    #[arg(long, default_value = "room.monitor")]
    echo_mic: String,
    /// Sentences per echo measurement (after the first, while the canceller adapts).
    #[arg(long, default_value_t = 6)]
    sentences: usize,
    /// The player's mouth for the double-talk measurement: a sink heard in the room.
    #[arg(long, default_value = "person")]
    echo_person: String,
}

/// What the player says over the robot in the double-talk measurement, one second into the
/// robot's longest sentence.
const PLAYER: &[&str] = &[
    "stop",
    "let's play",
    "touch the ball",
    "hello",
    "no",
    "look at the ball",
];

/// The player's words over the robot: their voiced 10 ms frames (within 30 dB of their peak),
/// and the frames of `audio/in` over the end-pointer's floor while they were said.
#[derive(Debug, Default, Clone, Copy)]
struct PlayerOver {
    voiced: usize,
    passed: usize,
}

impl PlayerOver {
    fn pct(&self) -> f64 {
        if self.voiced == 0 {
            0.0
        } else {
            100.0 * self.passed.min(self.voiced) as f64 / self.voiced as f64
        }
    }
}

/// A sentence sent on `audio/out` in 100 ms chunks from `start`, paced in real time as the
/// speech generator does.
struct Paced<'a> {
    start: Instant,
    chunks: std::iter::Peekable<std::iter::Enumerate<std::slice::Chunks<'a, i16>>>,
}

impl<'a> Paced<'a> {
    fn new(start: Instant, sentence: &'a [i16]) -> Self {
        Self {
            start,
            chunks: sentence.chunks(1600).enumerate().peekable(),
        }
    }

    /// Send the next chunk if it is due.
    async fn send_due(&mut self, out: &interfaces::Publisher<AudioChunk>) -> anyhow::Result<()> {
        let due = |k: usize| self.start + Duration::from_millis(100 * k as u64);
        if self
            .chunks
            .peek()
            .is_some_and(|(k, _)| Instant::now() >= due(*k))
            && let Some((_, c)) = self.chunks.next()
        {
            out.publish(&mut AudioChunk::mono(RATE_HZ, c)).await?;
        }
        Ok(())
    }
}

/// Say `utterance` into the sink `--echo-person` on a stream of its own, primed with silence
/// as `audio_io` primes the speaker: the thread playing it.
fn say_into(args: &Args, utterance: &[i16]) -> anyhow::Result<std::thread::JoinHandle<()>> {
    let mut play = pulse::Playback::open(
        Some(args.server.as_str()),
        &args.echo_person,
        RATE_HZ,
        1,
        BUFFER,
        "bench player",
    )?;
    let mut data = vec![0i16; (BUFFER.as_secs_f64() * f64::from(RATE_HZ)) as usize];
    data.extend_from_slice(utterance);
    Ok(std::thread::Builder::new()
        .name("bench-player".into())
        .spawn(move || {
            if play.write(&data).is_ok() {
                let _ = play.drain();
            }
        })?)
}

/// What the robot says in the echo measurement (the touch game's sentences).
const SENTENCES: &[&str] = &[
    "Hello, I am Loki. Nice to meet you!",
    "Great, let's play! Show me the ball and ask me to scan it.",
    "I'm looking for the ball.",
    "I'm going to touch the ball.",
    "Thank you! I'm moving my arm back.",
    "I cannot find the ball. Please show it to me.",
    "Did you say touch the ball?",
    "Thank you for playing. Goodbye!",
];

/// The recognizer's end-pointer hears nothing quieter (its `min_level_dbfs`).
const VAD_FLOOR_DBFS: f64 = -65.0;

/// The robot's voice in the room and in its microphone, over some sentences.
#[derive(Debug, Default, Clone, Copy)]
struct Echo {
    /// Mean levels over the sentences (dBFS).
    room_dbfs: f64,
    mic_dbfs: f64,
    /// Share of the microphone's 10 ms frames at or above [`VAD_FLOOR_DBFS`] (%).
    frames_over_floor_pct: f64,
}

impl Echo {
    fn erle_db(&self) -> f64 {
        self.room_dbfs - self.mic_dbfs
    }
}

fn dbfs(energy: f64, n: usize) -> f64 {
    if n == 0 || energy <= 0.0 {
        return -120.0;
    }
    10.0 * (energy / n as f64 / (32768.0 * 32768.0)).log10()
}

/// Sum of squares and count, and the 10 ms frames over the floor.
#[derive(Debug, Default)]
struct Levels {
    energy: f64,
    n: usize,
    frames: usize,
    loud_frames: usize,
}

impl Levels {
    fn add(&mut self, samples: &[i16]) {
        for f in samples.chunks(160) {
            let e: f64 = f.iter().map(|&x| f64::from(x) * f64::from(x)).sum();
            self.energy += e;
            self.n += f.len();
            if f.len() == 160 {
                self.frames += 1;
                if dbfs(e, f.len()) >= VAD_FLOOR_DBFS {
                    self.loud_frames += 1;
                }
            }
        }
    }
}

/// `audio_io` run in this process between `source` and `sink`, on a router of its own in
/// namespace `namespace`: the router (open while this is held), the bench's own bus on it,
/// the shutdown sender and the running component.
async fn start_audio_io(
    args: &Args,
    namespace: &str,
    source: &str,
    sink: &str,
    echo_cancel: EchoCancel,
    residual_echo: ResidualEcho,
) -> anyhow::Result<(
    Box<dyn std::any::Any + Send>,
    Bus,
    tokio::sync::watch::Sender<bool>,
    tokio::task::JoinHandle<anyhow::Result<()>>,
)> {
    let (router, endpoint) = open_router("tcp/127.0.0.1:0").await?;
    let connect = ConnectArgs::to_router(&endpoint, namespace);
    let config = Config {
        driver: Driver::Pulse,
        server: args.server.clone(),
        source: source.to_string(),
        sink: sink.to_string(),
        no_capture: false,
        no_playback: false,
        rate_hz: RATE_HZ,
        chunk_ms: 20,
        playback_buffer_ms: BUFFER.as_millis() as u32,
        reopen_s: 1.0,
        echo_cancel,
        pause_on_speech: false,
        resume_after_s: 0.8,
        residual_echo,
        array: None,
    };
    let prepared = component::prepare(config)?;
    let component_bus = Bus::open(&connect, "audio_io").await?;
    let (stop, shutdown) = Shutdown::new();
    let running = tokio::spawn(component::run(component_bus, prepared, shutdown));
    let bus = Bus::open(&connect, "bench_audio").await?;
    Ok((Box::new(router), bus, stop, running))
}

/// The robot's `sentences` through `audio_io` with `mode`: the first sentence (adapting) and
/// the rest.
async fn echo(
    args: &Args,
    (mode, residual): (EchoCancel, ResidualEcho),
    sentences: &[Vec<i16>],
    player: &[Vec<i16>],
) -> anyhow::Result<(Echo, Echo, PlayerOver)> {
    let (_router, bus, stop, running) = start_audio_io(
        args,
        &format!("bench-echo-{}-{mode:?}-{residual:?}", std::process::id()),
        &args.echo_mic,
        &args.echo_speaker,
        mode,
        residual,
    )
    .await?;
    let out = bus.publisher(&topics::AUDIO_OUT).await?;
    let heard = bus.subscriber(&topics::AUDIO_IN).await?;
    tokio::time::timeout(Duration::from_secs(10), heard.recv()).await??;
    // The room, straight from the server, beside audio_io's microphone.
    let (room_tx, room_rx) = mpsc::sync_channel::<Vec<i16>>(512);
    let room_stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let room = {
        let mut capture = pulse::Capture::open(
            Some(args.server.as_str()),
            &args.echo_mic,
            RATE_HZ,
            1,
            CHUNK_FRAMES,
            "bench room",
        )?;
        let stopped = room_stop.clone();
        std::thread::Builder::new()
            .name("bench-room".into())
            .spawn(move || {
                let mut buf = Vec::new();
                while !stopped.load(std::sync::atomic::Ordering::Relaxed)
                    && capture.read(&mut buf).is_ok()
                {
                    if room_tx.send(std::mem::take(&mut buf)).is_err() {
                        return;
                    }
                }
            })?
    };
    let mut results = Vec::new();
    for sentence in sentences {
        let (mut mic, mut in_room) = (Levels::default(), Levels::default());
        while room_rx.try_recv().is_ok() {}
        // The sentence in 100 ms chunks, paced in real time as the generator does, and what
        // the microphone and the room hear until 0.5 s after its end.
        let start = Instant::now();
        let end = start + Duration::from_secs_f64(sentence.len() as f64 / f64::from(RATE_HZ));
        let listen_until = end + BUFFER + Duration::from_millis(500);
        let mut paced = Paced::new(start, sentence);
        while Instant::now() < listen_until {
            paced.send_due(&out).await?;
            while let Ok(Ok(c)) = tokio::time::timeout(Duration::from_millis(5), heard.recv()).await
            {
                mic.add(&c.samples().unwrap_or_default());
            }
            while let Ok(r) = room_rx.try_recv() {
                in_room.add(&r);
            }
        }
        results.push((mic, in_room));
        // A pause between two sentences, as in a game.
        tokio::time::sleep(Duration::from_millis(300)).await;
    }
    // The player over the robot's longest sentence, one second into it.
    let mut over = PlayerOver::default();
    let long = sentences
        .iter()
        .max_by_key(|s| s.len())
        .map_or(&[][..], |s| &s[..]);
    for utterance in player {
        let levels: Vec<f64> = utterance
            .chunks_exact(160)
            .map(|f| dbfs(f.iter().map(|&x| f64::from(x).powi(2)).sum(), 160))
            .collect();
        let peak = levels.iter().copied().fold(-120.0, f64::max);
        over.voiced += levels.iter().filter(|&&l| l >= peak - 30.0).count();
        let said_s = utterance.len() as f64 / f64::from(RATE_HZ);
        let start = Instant::now();
        let end = start + Duration::from_secs_f64(long.len() as f64 / f64::from(RATE_HZ));
        let at = start + Duration::from_secs(1);
        let mut speaking = None;
        let mut window = None;
        let mut frames: Vec<(i64, f64)> = Vec::new();
        let mut paced = Paced::new(start, long);
        while Instant::now() < end + BUFFER + Duration::from_millis(500) {
            paced.send_due(&out).await?;
            if speaking.is_none() && Instant::now() >= at {
                // Her words reach the room a buffer and the room's loop-back later.
                let t0 = interfaces::clock::system_now_ns()
                    + (BUFFER + Duration::from_millis(20)).as_nanos() as i64;
                window = Some((t0 - 50_000_000, t0 + (said_s * 1e9) as i64 + 100_000_000));
                speaking = Some(say_into(args, utterance)?);
            }
            while let Ok(Ok(c)) = tokio::time::timeout(Duration::from_millis(5), heard.recv()).await
            {
                let samples = c.samples().unwrap_or_default();
                for (i, f) in samples.chunks_exact(160).enumerate() {
                    let e = f.iter().map(|&x| f64::from(x).powi(2)).sum();
                    frames.push((c.header.stamp_ns + i as i64 * 10_000_000, dbfs(e, 160)));
                }
            }
            while room_rx.try_recv().is_ok() {}
        }
        if let Some(t) = speaking {
            let _ = t.join();
        }
        if let Some((from, to)) = window {
            over.passed += frames
                .iter()
                .filter(|&&(t, l)| t >= from && t < to && l >= VAD_FLOOR_DBFS)
                .count();
        }
        tokio::time::sleep(Duration::from_millis(300)).await;
    }
    room_stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let _ = stop.send(true);
    let _ = running.await;
    drop(room_rx);
    let _ = room.join();
    let summary = |r: &[(Levels, Levels)]| {
        let (mut m, mut o) = (Levels::default(), Levels::default());
        for (a, b) in r {
            m.energy += a.energy;
            m.n += a.n;
            m.frames += a.frames;
            m.loud_frames += a.loud_frames;
            o.energy += b.energy;
            o.n += b.n;
        }
        Echo {
            room_dbfs: dbfs(o.energy, o.n),
            mic_dbfs: dbfs(m.energy, m.n),
            frames_over_floor_pct: if m.frames == 0 {
                0.0
            } else {
                100.0 * m.loud_frames as f64 / m.frames as f64
            },
        }
    };
    Ok((summary(&results[..1]), summary(&results[1..]), over))
}

const RATE_HZ: u32 = 16_000;
/// The playback buffer, as `audio_io`'s default.
const BUFFER: Duration = Duration::from_millis(200);
/// 20 ms capture chunks, as `audio_io`'s default.
const CHUNK_FRAMES: usize = 320;
/// A sample louder than this is the click (the room is otherwise digital silence).
const LOUD: u16 = 4000;

/// A 100 ms chunk starting with a 5 ms click.
fn click() -> Vec<i16> {
    let mut v = vec![0i16; 1600];
    for (i, s) in v.iter_mut().take(80).enumerate() {
        *s = if i % 2 == 0 { 12_000 } else { -12_000 };
    }
    v
}

fn percentile(v: &mut [f64], p: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let i = ((v.len() - 1) as f64 * p).round() as usize;
    v[i]
}

/// The floor: libpulse alone. Returns the round trips (ms).
fn floor(args: &Args) -> anyhow::Result<Vec<f64>> {
    let server = Some(args.server.as_str());
    let mut play = pulse::Playback::open(server, &args.sink, RATE_HZ, 1, BUFFER, "bench click")?;
    let mut capture =
        pulse::Capture::open(server, &args.source, RATE_HZ, 1, CHUNK_FRAMES, "bench mic")?;
    let (tx, rx) = mpsc::sync_channel::<Instant>(64);
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let stopped = stop.clone();
    let reader = std::thread::Builder::new()
        .name("bench-mic".into())
        .spawn(move || {
            let mut buf = Vec::new();
            while !stopped.load(std::sync::atomic::Ordering::Relaxed)
                && capture.read(&mut buf).is_ok()
            {
                if buf.iter().any(|s| s.unsigned_abs() > LOUD)
                    && tx.try_send(Instant::now()).is_err()
                {
                    return;
                }
            }
        })?;
    let pad = vec![0i16; (BUFFER.as_secs_f64() * f64::from(RATE_HZ)) as usize - 1600];
    let mut trips = Vec::new();
    for i in 0..args.warmup + args.clicks {
        std::thread::sleep(Duration::from_millis(args.gap_ms));
        while rx.try_recv().is_ok() {}
        let mut data = pad.clone();
        data.extend(click());
        let t0 = Instant::now();
        play.write(&data)?;
        if let Ok(t1) = rx.recv_timeout(Duration::from_secs(2))
            && i >= args.warmup
        {
            trips.push((t1 - t0).as_secs_f64() * 1000.0);
        }
        // The rest of the click's chunk.
        while rx.recv_timeout(Duration::from_millis(150)).is_ok() {}
    }
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    drop(play);
    let _ = reader.join();
    Ok(trips)
}

/// Through robocog: `audio/out` to `audio/in` via `audio_io`. Returns the round trips and the
/// capture-to-bus delays (ms).
async fn through_robocog(args: &Args) -> anyhow::Result<(Vec<f64>, Vec<f64>)> {
    let (_router, bus, stop, running) = start_audio_io(
        args,
        &format!("bench-audio-{}", std::process::id()),
        &args.source,
        &args.sink,
        EchoCancel::None,
        ResidualEcho::Keep,
    )
    .await?;
    let out = bus.publisher(&topics::AUDIO_OUT).await?;
    let heard = bus.subscriber(&topics::AUDIO_IN).await?;
    // Wait until the microphone's chunks arrive (the subscription has reached the router).
    tokio::time::timeout(Duration::from_secs(10), heard.recv()).await??;
    let mut trips = Vec::new();
    let mut capture = Vec::new();
    for i in 0..args.warmup + args.clicks {
        // Silence, and the capture delays meanwhile.
        let quiet_until = Instant::now() + Duration::from_millis(args.gap_ms);
        while let Ok(Ok(c)) = tokio::time::timeout_at(quiet_until.into(), heard.recv()).await {
            if i >= args.warmup {
                let now = interfaces::clock::system_now_ns();
                capture.push((now - c.header.stamp_ns) as f64 / 1e6);
            }
        }
        let t0 = Instant::now();
        out.publish(&mut AudioChunk::mono(RATE_HZ, &click()))
            .await?;
        let deadline = t0 + Duration::from_secs(2);
        while let Ok(Ok(c)) = tokio::time::timeout_at(deadline.into(), heard.recv()).await {
            if c.samples()
                .unwrap_or_default()
                .iter()
                .any(|s| s.unsigned_abs() > LOUD)
            {
                if i >= args.warmup {
                    trips.push(t0.elapsed().as_secs_f64() * 1000.0);
                }
                break;
            }
        }
    }
    let _ = stop.send(true);
    let _ = running.await;
    Ok((trips, capture))
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    // Quiet unless asked (RUST_LOG=audio_io::double_talk=debug tells when the player was heard).
    interfaces::node::init_logging_with("warn");
    let devices = pulse::devices(Some(&args.server))?;
    eprintln!(
        "sound server {}: {} clicks, one every {} ms",
        devices.server, args.clicks, args.gap_ms
    );
    let for_floor = args.clone();
    let mut direct = tokio::task::spawn_blocking(move || floor(&for_floor)).await??;
    let (mut trips, mut capture) = through_robocog(&args).await?;
    let missed = (args.clicks - trips.len()) + (args.clicks - direct.len());
    let (rt50, rt99) = (percentile(&mut trips, 0.5), percentile(&mut trips, 0.99));
    let (fl50, fl99) = (percentile(&mut direct, 0.5), percentile(&mut direct, 0.99));
    let (cap50, cap99) = (
        percentile(&mut capture, 0.5),
        percentile(&mut capture, 0.99),
    );
    println!("| path | p50 ms | p99 ms |");
    println!("|---|---:|---:|");
    println!(
        "| audio/out to audio/in through audio_io and the sound server | {rt50:.1} | {rt99:.1} |"
    );
    println!("| the same click through libpulse alone (the floor) | {fl50:.1} | {fl99:.1} |");
    println!(
        "| capture of a chunk's first sample to its arrival on audio/in | {cap50:.1} | {cap99:.1} |"
    );
    println!(
        "round trip over the floor: x{:.2} at p50 (+{:.1} ms); {} clicks missed",
        rt50 / fl50,
        rt50 - fl50,
        missed
    );
    // The robot's voice in its microphone, without and with the canceller.
    let voice = audio::synth::Voice::default();
    let mut sentences = Vec::new();
    for text in SENTENCES.iter().cycle().take(args.sentences + 1) {
        sentences.push(audio::synth::synthesize_16k(text, &voice)?);
    }
    eprintln!(
        "the robot's voice in its microphone: {} sentences on {:?}, microphone {:?}",
        sentences.len(),
        args.echo_speaker,
        args.echo_mic
    );
    let player_voice = audio::synth::Voice {
        voice: "en-us+f3".into(),
        ..audio::synth::Voice::default()
    };
    let mut player = Vec::new();
    for text in PLAYER {
        player.push(audio::synth::synthesize_16k(text, &player_voice)?);
    }
    let (_, none, _) = echo(
        &args,
        (EchoCancel::None, ResidualEcho::Keep),
        &sentences,
        &[],
    )
    .await?;
    let (aec_first, aec, aec_player) = echo(
        &args,
        (EchoCancel::Webrtc, ResidualEcho::Keep),
        &sentences,
        &player,
    )
    .await?;
    let (sup_first, sup, sup_player) = echo(
        &args,
        (EchoCancel::Webrtc, ResidualEcho::Suppress),
        &sentences,
        &player,
    )
    .await?;
    println!();
    println!(
        "| the robot's voice | in the room dBFS | on audio/in dBFS | ERLE dB | audio/in frames over {VAD_FLOOR_DBFS} dBFS |"
    );
    println!("|---|---:|---:|---:|---:|");
    for (name, e) in [
        ("no canceller (the peer)", none),
        ("WebRTC canceller, first sentence (adapting)", aec_first),
        ("WebRTC canceller, the next sentences", aec),
        (
            "canceller and double-talk detector, first sentence",
            sup_first,
        ),
        (
            "canceller and double-talk detector, the next sentences",
            sup,
        ),
    ] {
        println!(
            "| {name} | {:.1} | {:.1} | {:.1} | {:.1} % |",
            e.room_dbfs,
            e.mic_dbfs,
            e.erle_db(),
            e.frames_over_floor_pct
        );
    }
    println!();
    println!(
        "| the player over the robot ({} utterances, 1 s into its longest sentence) | her voiced frames on audio/in over {VAD_FLOOR_DBFS} dBFS |",
        PLAYER.len()
    );
    println!("|---|---:|");
    println!(
        "| WebRTC canceller alone (the peer) | {:.1} % |",
        aec_player.pct()
    );
    println!(
        "| canceller and double-talk detector | {:.1} % |",
        sup_player.pct()
    );
    println!(
        "{}",
        serde_json::json!({
            "player_over_robot_passed_pct": round1(sup_player.pct()),
            "peer_canceller_player_over_robot_passed_pct": round1(aec_player.pct()),
            "player_over_robot_passed_ratio_vs_canceller": if aec_player.pct() > 0.0 {
                (sup_player.pct() / aec_player.pct() * 100.0).round() / 100.0
            } else {
                0.0
            },
            "clicks": args.clicks,
            "echo_sentences": args.sentences,
            "echo_room_dbfs": round1(aec.room_dbfs),
            "echo_mic_dbfs": round1(aec.mic_dbfs),
            "echo_erle_db": round1(aec.erle_db()),
            "echo_frames_over_vad_floor_pct": round1(aec.frames_over_floor_pct),
            "echo_adapting_erle_db": round1(aec_first.erle_db()),
            "echo_adapting_frames_over_vad_floor_pct": round1(aec_first.frames_over_floor_pct),
            "suppressed_frames_over_vad_floor_pct": round1(sup.frames_over_floor_pct),
            "suppressed_adapting_frames_over_vad_floor_pct": round1(sup_first.frames_over_floor_pct),
            "peer_no_canceller_erle_db": round1(none.erle_db()),
            "peer_no_canceller_frames_over_vad_floor_pct": round1(none.frames_over_floor_pct),
            "erle_gain_db_vs_no_canceller": round1(aec.erle_db() - none.erle_db()),
            "round_trip_p50_ms": round1(rt50),
            "round_trip_p99_ms": round1(rt99),
            "libpulse_round_trip_p50_ms": round1(fl50),
            "libpulse_round_trip_p99_ms": round1(fl99),
            "round_trip_p50_ratio_vs_libpulse": (rt50 / fl50 * 100.0).round() / 100.0,
            "capture_to_bus_p50_ms": round1(cap50),
            "capture_to_bus_p99_ms": round1(cap99),
            "missed_clicks": missed,
        })
    );
    anyhow::ensure!(missed == 0, "{missed} clicks never came back");
    Ok(())
}

fn round1(x: f64) -> f64 {
    (x * 10.0).round() / 10.0
}
