//! Delay-and-sum and MVDR: gain towards the target, rejection of an interferer, streaming, bad
//! input.

use super::*;

/// Beamforms `channels` in one call of `process` (a beamformer's), returning the output.
fn run(
    channels: &[Vec<f64>],
    mut process: impl FnMut(Multichannel<'_>, &mut Vec<f32>) -> Result<(), ArrayError>,
) -> Vec<f32> {
    let samples = as_f32(channels);
    let slices: Vec<&[f32]> = samples.iter().map(Vec::as_slice).collect();
    let mut out = Vec::new();
    process(Multichannel::Planar(&slices), &mut out).unwrap();
    out
}

/// Beamforms `channels` in chunks of `chunk` samples, concatenating the outputs.
fn run_in_chunks(
    channels: &[Vec<f64>],
    chunk: usize,
    mut process: impl FnMut(Multichannel<'_>, &mut Vec<f32>) -> Result<(), ArrayError>,
) -> Vec<f32> {
    let samples = as_f32(channels);
    let mut all = Vec::new();
    let mut out = Vec::new();
    for start in (0..samples[0].len()).step_by(chunk) {
        let slices: Vec<&[f32]> = samples
            .iter()
            .map(|c| &c[start..(start + chunk).min(c.len())])
            .collect();
        process(Multichannel::Planar(&slices), &mut out).unwrap();
        assert_eq!(out.len(), slices[0].len());
        all.extend_from_slice(&out);
    }
    all
}

/// Where the output has settled: past the latency and the first frame.
fn settled_from(latency: usize) -> usize {
    latency + 512
}

/// The output's settled samples and the input samples they stand for (`latency` earlier).
fn aligned<'a>(out: &'a [f32], input: &'a [f64], latency: usize) -> (&'a [f32], &'a [f64]) {
    let skip = settled_from(latency);
    (&out[skip..], &input[skip - latency..input.len() - latency])
}

/// How much a beamformer improves the SINR over the first microphone (dB), from the outputs
/// for the target and for the rest apart (a beamformer is linear while its weights are fixed).
fn sinr_gain_db(
    target_in: &[Vec<f64>],
    rest_in: &[Vec<f64>],
    target_out: &[f32],
    rest_out: &[f32],
    latency: usize,
) -> f64 {
    let skip = settled_from(latency);
    db(power(&target_out[skip..]) / power(&rest_out[skip..]))
        - db(power(&target_in[0]) / power(&rest_in[0]))
}

#[test]
fn delay_and_sum_passes_the_steered_target_unchanged() {
    for (name, azimuth_deg) in [
        ("circular_4", 0.0),
        ("circular_6", -100.0),
        ("kinect_v1", 40.0),
    ] {
        let geometry = ArrayGeometry::builtin(name).unwrap();
        let mono = white(RATE, 0.01, 1);
        let channels = from_azimuth(&geometry, &mono, azimuth_deg);
        let mut das = DelayAndSum::new(&geometry);
        das.steer(direction(f64::to_radians(azimuth_deg), 0.0))
            .unwrap();
        let out = run(&channels, |input, out| das.process(input, out));
        assert_eq!(out.len(), mono.len());
        let (out, input) = aligned(&out, &mono, das.latency_samples());
        let gain_db = db(power(out) / power(input));
        assert!(gain_db.abs() < 1.0, "{name}: {gain_db} dB");
        // Sample for sample, `latency_samples` late (measured: -34.6, -33.8, -32.5 dB; what is
        // left is the frames' circular shifts).
        let error: Vec<f64> = out
            .iter()
            .zip(input)
            .map(|(&y, x)| f64::from(y) - x)
            .collect();
        let error_db = db(power(&error) / power(input));
        assert!(error_db < -30.0, "{name}: error {error_db} dB");
    }
}

#[test]
fn delay_and_sum_attenuates_an_interferer() {
    // Broadband white noise from 0° (target) and 60° (interferer), equal power. Measured SNR
    // gains: circular_4 4.16 dB, circular_6 5.85 dB, kinect_v1 7.29 dB (a small array gains
    // little at low frequencies, where the wavelength dwarfs it).
    for (name, floor_db) in [("circular_4", 3.5), ("circular_6", 5.0), ("kinect_v1", 6.5)] {
        let geometry = ArrayGeometry::builtin(name).unwrap();
        let target = from_azimuth(&geometry, &white(RATE, 0.01, 1), 0.0);
        let interferer = from_azimuth(&geometry, &white(RATE, 0.01, 2), 60.0);
        let das = DelayAndSum::new(&geometry);
        let target_out = run(&target, |i, o| das.clone().process(i, o));
        let interferer_out = run(&interferer, |i, o| das.clone().process(i, o));
        let latency = das.latency_samples();
        let gain = sinr_gain_db(&target, &interferer, &target_out, &interferer_out, latency);
        assert!(gain >= floor_db, "{name}: {gain:.2} dB");
    }
}

#[test]
fn mvdr_nulls_a_learned_interferer_and_keeps_the_target() {
    // As above, with a little sensor noise (-40 dB) on each microphone, and the interferer
    // learned on a second of target silence. Measured SINR gains: circular_4 16.5 dB (delay-and-
    // sum 4.2), kinect_v1 21.8 dB (7.3); 1 % diagonal loading costs about 4 dB of that.
    for (name, floor_db) in [("circular_4", 15.0), ("kinect_v1", 20.0)] {
        let geometry = ArrayGeometry::builtin(name).unwrap();
        let mics = geometry.channels();
        let mut mvdr = Mvdr::new(&geometry);
        let learn = mix(
            &from_azimuth(&geometry, &white(RATE, 0.01, 3), 60.0),
            &uncorrelated(mics, RATE, 1e-6, 4),
        );
        run(&learn, |i, o| mvdr.process(i, false, o));
        assert_eq!(mvdr.noise_frames(), RATE / 256);
        let mono = white(RATE, 0.01, 1);
        let target = from_azimuth(&geometry, &mono, 0.0);
        let rest = mix(
            &from_azimuth(&geometry, &white(RATE, 0.01, 2), 60.0),
            &uncorrelated(mics, RATE, 1e-6, 5),
        );
        let latency = mvdr.latency_samples();
        let target_out = run(&target, |i, o| mvdr.clone().process(i, true, o));
        let rest_out = run(&rest, |i, o| mvdr.clone().process(i, true, o));
        let gain = sinr_gain_db(&target, &rest, &target_out, &rest_out, latency);
        let das = DelayAndSum::new(&geometry);
        let das_gain = sinr_gain_db(
            &target,
            &rest,
            &run(&target, |i, o| das.clone().process(i, o)),
            &run(&rest, |i, o| das.clone().process(i, o)),
            latency,
        );
        assert!(gain >= floor_db, "{name}: MVDR {gain:.2} dB");
        assert!(
            gain >= das_gain + 10.0,
            "{name}: MVDR {gain:.2} dB, DAS {das_gain:.2} dB"
        );
        // Distortionless: the lone target comes through at its level (measured: 0.0 dB).
        let (out, input) = aligned(&target_out, &mono, latency);
        let target_db = db(power(out) / power(input));
        assert!(target_db.abs() < 1.0, "{name}: target {target_db:.2} dB");
    }
}

#[test]
fn mvdr_is_delay_and_sum_until_it_has_heard_enough_noise() {
    let geometry = ArrayGeometry::builtin("circular_6").unwrap();
    let noise = mix(
        &from_azimuth(&geometry, &white(RATE / 2, 0.01, 3), 60.0),
        &uncorrelated(6, RATE / 2, 1e-4, 4),
    );
    // 15 target-silent frames (3840 samples) are one too few.
    let first = (Mvdr::MIN_NOISE_FRAMES - 1) * 256;
    let head: Vec<Vec<f64>> = noise.iter().map(|c| c[..first].to_vec()).collect();
    let tail: Vec<Vec<f64>> = noise.iter().map(|c| c[first..].to_vec()).collect();
    let mut mvdr = Mvdr::new(&geometry);
    let mut das = DelayAndSum::new(&geometry);
    let steering = direction(-1.0, 0.0);
    mvdr.steer(steering).unwrap();
    das.steer(steering).unwrap();
    assert_eq!(
        run(&head, |i, o| mvdr.process(i, false, o)),
        run(&head, |i, o| das.process(i, o))
    );
    assert_eq!(mvdr.noise_frames(), Mvdr::MIN_NOISE_FRAMES - 1);
    // One more, and it adapts: by the end it lets much less of the noise through.
    let (mvdr_out, das_out) = (
        run(&tail, |i, o| mvdr.process(i, false, o)),
        run(&tail, |i, o| das.process(i, o)),
    );
    let end = tail[0].len() - 2048;
    // Measured: -11.8 dB (the sensor noise, 20 dB under the interferer, bounds it).
    let less_db = db(power(&mvdr_out[end..]) / power(&das_out[end..]));
    assert!(less_db < -8.0, "{less_db} dB");
}

#[test]
fn chunk_size_does_not_matter() {
    let geometry = ArrayGeometry::builtin("circular_6").unwrap();
    let channels = mix(
        &from_azimuth(&geometry, &white(RATE / 2, 0.01, 1), 20.0),
        &from_azimuth(&geometry, &white(RATE / 2, 0.01, 2), -70.0),
    );
    let mut das = DelayAndSum::new(&geometry);
    das.steer(direction(20f64.to_radians(), 0.0)).unwrap();
    let whole = run(&channels, |i, o| das.clone().process(i, o));
    // 20 ms at 16 kHz, a sample at a time, odd sizes, more than a frame.
    for chunk in [320, 1, 7, 1000] {
        let mut fresh = das.clone();
        assert_eq!(
            run_in_chunks(&channels, chunk, |i, o| fresh.process(i, o)),
            whole,
            "chunks of {chunk}"
        );
    }
    // MVDR too: learning on the first 8000 samples (a whole number of chunks), then not.
    let mvdr = Mvdr::new(&geometry);
    let split = 8000;
    let mut calls = 0;
    let mut whole_mvdr = mvdr.clone();
    let mut halves = |chunk: usize, m: &mut Mvdr| {
        let mut done = 0;
        run_in_chunks(&channels, chunk, |i, o| {
            calls += 1;
            let learning = done < split;
            let len = match i {
                Multichannel::Planar(s) => s[0].len(),
                Multichannel::Interleaved(s) => s.len() / 6,
            };
            done += len;
            m.process(i, !learning, o)
        })
    };
    let in_two = halves(split, &mut whole_mvdr);
    let in_chunks = halves(320, &mut mvdr.clone());
    assert!(calls > 2);
    assert_eq!(in_chunks, in_two);
}

#[test]
fn interleaved_i16_and_planar_f32_give_the_same_output() {
    let geometry = ArrayGeometry::builtin("kinect_v1").unwrap();
    let channels: Vec<Vec<f64>> = from_azimuth(&geometry, &white(RATE / 4, 0.01, 1), 30.0)
        .into_iter()
        .map(|c| c.into_iter().map(f64::round).collect())
        .collect();
    let interleaved: Vec<i16> = (0..channels[0].len())
        .flat_map(|t| channels.iter().map(move |c| c[t] as i16))
        .collect();
    let das = DelayAndSum::new(&geometry);
    let mut from_i16 = Vec::new();
    das.clone()
        .process(Multichannel::Interleaved(&interleaved), &mut from_i16)
        .unwrap();
    assert_eq!(from_i16, run(&channels, |i, o| das.clone().process(i, o)));
}

#[test]
fn steering_can_change_between_chunks() {
    // Target at 0°, interferer at 90°: steered at the target, then at the interferer.
    let geometry = ArrayGeometry::builtin("circular_6").unwrap();
    let target = from_azimuth(&geometry, &white(RATE, 0.01, 1), 0.0);
    let interferer = from_azimuth(&geometry, &white(RATE, 0.01, 2), 90.0);
    let half = RATE / 2;
    let steered = |channels: &[Vec<f64>]| {
        let mut das = DelayAndSum::new(&geometry);
        let mut out = Vec::new();
        for (start, azimuth) in [(0, 0.0), (half, 90f64.to_radians())] {
            das.steer(direction(azimuth, 0.0)).unwrap();
            let part: Vec<Vec<f64>> = channels
                .iter()
                .map(|c| c[start..start + half].to_vec())
                .collect();
            out.extend(run(&part, |i, o| das.process(i, o)));
        }
        out
    };
    let (t, i) = (steered(&target), steered(&interferer));
    let sir_db = |range: std::ops::Range<usize>| db(power(&t[range.clone()]) / power(&i[range]));
    // Measured: +8.0 dB before, -7.8 dB after (from a frame after the change on).
    let (before, after) = (sir_db(1024..half), sir_db(half + 1024..RATE));
    assert!(before > 6.0 && after < -6.0, "{before} dB, then {after} dB");
}

#[test]
fn bad_input_is_an_error_and_leaves_the_stream_as_it_was() {
    let geometry = ArrayGeometry::builtin("kinect_v1").unwrap();
    let channels = from_azimuth(&geometry, &white(2000, 0.01, 1), 30.0);
    let reference = run(&channels, |i, o| DelayAndSum::new(&geometry).process(i, o));
    let mut das = DelayAndSum::new(&geometry);
    let mut mvdr = Mvdr::new(&geometry);
    let mut out = vec![1.0];
    let partial = Multichannel::Interleaved(&[1, 2, 3, 4, 5, 6, 7]);
    let err = das.process(partial, &mut out).unwrap_err();
    assert!(
        matches!(
            err,
            ArrayError::PartialFrame {
                len: 7,
                channels: 4
            }
        ),
        "{err}"
    );
    assert!(mvdr.process(partial, false, &mut out).is_err());
    let a = [0.0f32; 10];
    let short = [0.0f32; 9];
    let nan = [0.0, f32::NAN, 0.0];
    let err = das
        .process(Multichannel::Planar(&[&a, &a, &a]), &mut out)
        .unwrap_err();
    assert_eq!(
        err.to_string(),
        "the source has 3 channels but the geometry kinect_v1 has 4 microphones"
    );
    let err = das
        .process(Multichannel::Planar(&[&a, &a, &short, &a]), &mut out)
        .unwrap_err();
    assert!(
        matches!(
            err,
            ArrayError::RaggedChannels {
                channel: 2,
                len: 9,
                expected: 10
            }
        ),
        "{err}"
    );
    let err = das
        .process(Multichannel::Planar(&[&nan, &nan, &nan, &nan]), &mut out)
        .unwrap_err();
    assert!(
        matches!(
            err,
            ArrayError::NonFiniteSample {
                channel: 0,
                index: 1
            }
        ),
        "{err}"
    );
    for bad in [[0.0; 3], [f64::NAN, 0.0, 0.0], [f64::INFINITY, 1.0, 0.0]] {
        assert!(matches!(das.steer(bad), Err(ArrayError::BadDirection(_))));
        assert!(matches!(mvdr.steer(bad), Err(ArrayError::BadDirection(_))));
    }
    // Nothing of it went in.
    assert_eq!(run(&channels, |i, o| das.process(i, o)), reference);
    // An empty chunk is no error.
    das.process(Multichannel::Interleaved(&[]), &mut out)
        .unwrap();
    assert!(out.is_empty());
}

#[test]
fn digital_silence_gives_silence() {
    let geometry = ArrayGeometry::builtin("circular_4").unwrap();
    let zeros = vec![0i16; 4 * RATE / 2];
    let mut out = Vec::new();
    let mut das = DelayAndSum::new(&geometry);
    das.process(Multichannel::Interleaved(&zeros), &mut out)
        .unwrap();
    assert!(out.iter().all(|&y| y == 0.0));
    // MVDR learning the silence as its noise (more frames than it needs) stays finite.
    let mut mvdr = Mvdr::new(&geometry);
    mvdr.process(Multichannel::Interleaved(&zeros), false, &mut out)
        .unwrap();
    assert!(mvdr.noise_frames() > Mvdr::MIN_NOISE_FRAMES);
    assert!(out.iter().all(|&y| y == 0.0));
    let sound = from_azimuth(&geometry, &white(RATE / 4, 0.01, 1), 0.0);
    let out = run(&sound, |i, o| mvdr.process(i, true, o));
    assert!(out.iter().all(|y| y.is_finite()));
    assert!(power(&out) > 0.0);
}

#[test]
fn the_simulator_refuses_a_bad_direction_or_rate() {
    let geometry = ArrayGeometry::builtin("laptop_2").unwrap();
    let render = |d, rate| sim::render_plane_wave(&geometry, &[1.0, 2.0], d, rate);
    assert!(matches!(
        render([0.0; 3], 16e3),
        Err(ArrayError::BadDirection(_))
    ));
    assert!(matches!(
        render([1.0, 0.0, 0.0], 0.0),
        Err(ArrayError::BadRate(_))
    ));
    assert!(matches!(
        render([1.0, 0.0, 0.0], f64::NAN),
        Err(ArrayError::BadRate(_))
    ));
    // From the left, the left microphone hears it 35 mm / 343 m/s early, the right one as much
    // late: fractional delays of 1.63 samples, exact for a band-limited signal.
    let mono: Vec<f64> = (0..4096).map(|t| (0.05 * t as f64).sin()).collect();
    let channels = sim::render_plane_wave(&geometry, &mono, [0.0, 1.0, 0.0], 16e3).unwrap();
    let lead = 0.035 / SPEED_OF_SOUND_M_S * 16e3;
    let samples = channels[0].iter().zip(&channels[1]).enumerate();
    for (t, (left, right)) in samples.skip(1000).take(2000) {
        assert!((left - (0.05 * (t as f64 + lead)).sin()).abs() < 1e-3);
        assert!((right - (0.05 * (t as f64 - lead)).sin()).abs() < 1e-3);
    }
}
