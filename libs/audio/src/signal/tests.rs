use super::*;

fn tone(hz: f64, rate: u32, secs: f64) -> Vec<i16> {
    (0..(rate as f64 * secs) as usize)
        .map(|i| (8000.0 * (2.0 * std::f64::consts::PI * hz * i as f64 / rate as f64).sin()) as i16)
        .collect()
}

#[test]
fn resampling_keeps_in_band_tones_and_removes_aliases() {
    let a = resample(&tone(1000.0, 22050, 1.0), 22050, 16000);
    assert!((a.len() as i64 - 16000).abs() <= 1);
    // Power of a sine of amplitude 8000: (8000/32768)^2 / 2.
    let expect = (8000.0f64 / 32768.0).powi(2) / 2.0;
    let p = power(&a[500..15500]);
    assert!((p / expect - 1.0).abs() < 0.05, "{p} vs {expect}");
    // 10 kHz is above the new Nyquist (8 kHz): it must be filtered, not folded to 6 kHz.
    let b = resample(&tone(10_000.0, 22050, 1.0), 22050, 16000);
    assert!(power(&b[500..15500]) < expect * 0.01);
}

#[test]
fn mixing_hits_the_requested_snr() {
    let speech = tone(440.0, 16000, 1.0);
    let mut rng = NoiseRng::new(7);
    for snr in [0.0, 10.0, 20.0] {
        let mixed = mix_at_snr(&speech, snr, NoiseKind::White, 0.5, 0.5, &mut rng);
        assert_eq!(mixed.len(), 32000);
        let noise_only = power(&mixed[..8000]);
        let measured = 10.0 * (active_power(&speech) / noise_only).log10();
        assert!(
            (measured - snr).abs() < 0.5,
            "asked {snr} dB, got {measured}"
        );
    }
    let clean = mix_at_snr(&speech, f64::INFINITY, NoiseKind::Brown, 0.1, 0.0, &mut rng);
    assert!(clean[..1600].iter().all(|&s| s == 0));
}

#[test]
fn gain_clips_at_full_scale() {
    let c = gain_clipped(&[20000, -20000, 100], 4.0);
    assert_eq!(c, vec![32767, -32768, 400]);
}

mod dc_tests {
    use super::*;

    #[test]
    fn an_offset_is_removed_and_a_clean_stream_is_untouched() {
        let tone: Vec<i16> = (0..32_000)
            .map(|i| {
                (3000.0 * (i as f64 * 2.0 * std::f64::consts::PI * 200.0 / 16_000.0).sin()) as i16
            })
            .collect();
        let mut dc = DcRemover::default();
        let mut out = Vec::new();
        dc.process(&tone, &mut out);
        assert_eq!(out, tone, "no offset: unchanged");
        let silence = vec![0i16; 1600];
        dc.process(&silence, &mut out);
        assert!(out.iter().all(|&s| s == 0), "digital silence stays zeros");

        let offset: Vec<i16> = tone.iter().map(|&s| s + 4000).collect();
        let mut dc = DcRemover::default();
        dc.process(&offset, &mut out);
        // After a second (four time constants) the mean of the output is near zero and the tone
        // is intact.
        let tail = &out[16_000..];
        let mean = tail.iter().map(|&s| f64::from(s)).sum::<f64>() / tail.len() as f64;
        assert!(mean.abs() < 100.0, "mean {mean}");
        let peak = tail.iter().map(|&s| s.abs()).max().unwrap_or(0);
        assert!((2800..=3300).contains(&peak), "peak {peak}");
        assert!((dc.offset() - 4000.0).abs() < 100.0, "{}", dc.offset());
    }

    /// A microphone whose offset (+3000) is there from its first sample, under quiet noise and
    /// after a stretch of digital silence: the offset is gone from the first 10 ms of sound on,
    /// not decaying over a second.
    #[test]
    fn an_offset_there_from_the_start_is_removed_at_once() {
        let mut rng = NoiseRng::new(7);
        let mut stream = vec![0i16; 800];
        stream.extend((0..16_000).map(|_| (3000.0 + 30.0 * rng.gaussian()).round() as i16));
        let mut dc = DcRemover::default();
        let mut out = Vec::new();
        let mut all = Vec::new();
        // 20 ms chunks, as a sound server's.
        for c in stream.chunks(320) {
            dc.process(c, &mut out);
            all.extend_from_slice(&out);
        }
        assert!(all[..800].iter().all(|&s| s == 0), "digital silence kept");
        for (k, w) in all[800..].chunks(160).enumerate() {
            let mean = w.iter().map(|&s| f64::from(s)).sum::<f64>() / w.len() as f64;
            assert!(mean.abs() < 10.0, "10 ms frame {k}: mean {mean}");
        }
    }
}

mod room_tests {
    use super::*;
    use rustfft::{FftPlanner, num_complex::Complex};
    use std::f64::consts::PI;

    /// Power per DFT bin of `x` (bins of `RATE / x.len()` Hz, first half only).
    fn spectrum(x: &[f64]) -> Vec<f64> {
        let mut z: Vec<Complex<f64>> = x.iter().map(|&v| Complex::new(v, 0.0)).collect();
        FftPlanner::<f64>::new()
            .plan_fft_forward(z.len())
            .process(&mut z);
        z[..x.len() / 2].iter().map(|c| c.norm_sqr()).collect()
    }

    fn power_f64(x: &[f64]) -> f64 {
        x.iter().map(|v| (v / 32768.0).powi(2)).sum::<f64>() / x.len() as f64
    }

    fn db(ratio: f64) -> f64 {
        10.0 * ratio.log10()
    }

    /// RT60 from Schroeder's backward integration: a straight-line fit of the energy decay curve
    /// between -5 and -25 dB, extrapolated to -60 dB.
    fn schroeder_rt60(h: &[f64]) -> f64 {
        let mut edc: Vec<f64> = h.iter().map(|x| x * x).collect();
        for i in (0..edc.len() - 1).rev() {
            edc[i] += edc[i + 1];
        }
        let total = edc[0];
        let points: Vec<(f64, f64)> = edc
            .iter()
            .enumerate()
            .map(|(i, &e)| (i as f64 / RATE, db(e / total)))
            .filter(|&(_, d)| (-25.0..=-5.0).contains(&d))
            .collect();
        let n = points.len() as f64;
        let mt = points.iter().map(|p| p.0).sum::<f64>() / n;
        let md = points.iter().map(|p| p.1).sum::<f64>() / n;
        let cov: f64 = points.iter().map(|p| (p.0 - mt) * (p.1 - md)).sum();
        let var: f64 = points.iter().map(|p| (p.0 - mt).powi(2)).sum();
        -60.0 / (cov / var)
    }

    /// A talker: a tone at `hz` with two harmonics, in 250 ms syllables (10 ms ramps) separated
    /// by 120 ms pauses, `syllables` of them, peak amplitude `amp`.
    fn talker(hz: f64, amp: f64, syllables: usize) -> Vec<i16> {
        let (on, off) = (4000, 1920);
        let mut v = Vec::new();
        for _ in 0..syllables {
            for i in 0..on {
                let t = v.len() as f64 / RATE;
                let ramp = (i.min(on - i) as f64 / 160.0).min(1.0);
                let x = (2.0 * PI * hz * t).sin() + 0.3 * (4.0 * PI * hz * t).sin();
                v.push((amp * ramp * x / 1.3) as i16);
            }
            v.extend(std::iter::repeat_n(0, off));
        }
        v
    }

    /// The quietest 100 ms window (10 ms steps) of `x`, in dB under its mean power.
    fn quietest_100ms_db(x: &[f64]) -> f64 {
        let mean = power_f64(x);
        (0..=(x.len() - 1600) / 160)
            .map(|k| db(power_f64(&x[k * 160..k * 160 + 1600]) / mean))
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn fan_noise_has_the_power_a_low_spectrum_and_a_blade_tone() {
        for seed in [1, 2, 3] {
            let params = FanParams::draw(&mut NoiseRng::new(seed));
            let n = 32_000;
            let x = noise(n, NoiseKind::Fan, 1e-3, &mut NoiseRng::new(seed));
            assert_eq!(x.len(), n);
            let p = power_f64(&x);
            assert!(db(p / 1e-3).abs() < 0.5, "power {p}");
            // Bins of 0.5 Hz.
            let spec = spectrum(&x);
            let hz = |k: usize| k as f64 * RATE / n as f64;
            let total: f64 = spec.iter().sum();
            let low: f64 = spec
                .iter()
                .enumerate()
                .filter(|&(k, _)| hz(k) < 1000.0)
                .map(|e| e.1)
                .sum();
            assert!(
                low / total > 0.8,
                "seed {seed}: {:.1} % under 1 kHz",
                100.0 * low / total
            );
            // The strongest bin between 50 Hz and 1 kHz is the blade-pass tone, far above the
            // noise around it.
            let (peak, peak_power) = spec
                .iter()
                .enumerate()
                .filter(|&(k, _)| (50.0..1000.0).contains(&hz(k)))
                .fold(
                    (0, 0.0),
                    |best, (k, &p)| if p > best.1 { (k, p) } else { best },
                );
            assert!(
                (hz(peak) - params.blade_hz).abs() < 1.0,
                "seed {seed}: peak at {} Hz, blade pass {} Hz",
                hz(peak),
                params.blade_hz
            );
            let mut around: Vec<f64> = spec
                .iter()
                .enumerate()
                .filter(|&(k, _)| (hz(k) - params.blade_hz).abs() < 40.0)
                .map(|e| *e.1)
                .collect();
            around.sort_by(f64::total_cmp);
            let median = around[around.len() / 2];
            assert!(
                db(peak_power / median) > 15.0,
                "seed {seed}: peak only {} dB",
                db(peak_power / median)
            );
        }
    }

    #[test]
    fn babble_has_no_silent_stretch_and_equal_talkers() {
        // The same rhythm for all three, so without random offsets their pauses would coincide.
        let talkers = vec![
            talker(300.0, 1000.0, 8),
            talker(1100.0, 6000.0, 11),
            talker(1900.0, 20000.0, 13),
        ];
        for t in &talkers {
            let t: Vec<f64> = t.iter().map(|&s| s as f64).collect();
            assert!(quietest_100ms_db(&t) < -60.0, "each talker has pauses");
        }
        let n = 80_000;
        let b = babble(&talkers, n, 1e-2, &mut NoiseRng::new(5));
        assert_eq!(b.len(), n);
        assert!(db(power_f64(&b) / 1e-2).abs() < 0.01);
        let quietest = quietest_100ms_db(&b);
        assert!(
            quietest > -10.0,
            "a 100 ms stretch {quietest} dB under the mean"
        );
        // Equal active power per talker: equal energy around each talker's tones.
        let spec = spectrum(&b);
        let band = |hz: f64| -> f64 {
            let k = (hz * n as f64 / RATE) as usize;
            let w = (60.0 * n as f64 / RATE) as usize;
            spec[k - w..k + w].iter().sum::<f64>()
                + spec[2 * k - 2 * w..2 * k + 2 * w].iter().sum::<f64>()
        };
        let levels = [band(300.0), band(1100.0), band(1900.0)];
        for l in levels {
            assert!(db(l / levels[0]).abs() < 1.0, "talker levels {levels:?}");
        }
    }

    #[test]
    fn mixing_with_a_given_noise_hits_the_snr() {
        let speech = talker(200.0, 8000.0, 3);
        let talkers = vec![talker(150.0, 3000.0, 9), talker(230.0, 9000.0, 7)];
        let nz = babble(&talkers, 40_000, 1e-3, &mut NoiseRng::new(9));
        let lead = 8000;
        for snr in [0.0, 10.0, 20.0] {
            let mixed = mix_with_noise(&speech, snr, &nz, 0.5, 0.5);
            assert_eq!(mixed.len(), lead + speech.len() + 8000);
            let residual: Vec<f64> = mixed
                .iter()
                .enumerate()
                .map(|(i, &m)| {
                    let s = if i >= lead && i < lead + speech.len() {
                        speech[i - lead]
                    } else {
                        0
                    };
                    m as f64 - s as f64
                })
                .collect();
            let measured = db(active_power(&speech) / power_f64(&residual));
            assert!(
                (measured - snr).abs() < 0.5,
                "asked {snr} dB, got {measured}"
            );
        }
        let clean = mix_with_noise(&speech, f64::INFINITY, &nz, 0.5, 0.5);
        assert!(clean[..lead].iter().all(|&s| s == 0));
        assert_eq!(clean[lead..lead + speech.len()], speech[..]);
        // A noise shorter than the mix is repeated.
        let short = mix_with_noise(&speech, 10.0, &nz[..1000], 0.5, 0.5);
        assert_eq!(short.len(), speech.len() + 16_000);
        assert_eq!(short[..1000], short[1000..2000]);
        assert!(short[..1000].iter().any(|&s| s != 0));
    }

    /// `noise` and `mix_at_snr` as they were before the fan noise and `mix_with_noise`.
    fn old_noise(n: usize, kind: NoiseKind, power_fs: f64, rng: &mut NoiseRng) -> Vec<f64> {
        let mut v: Vec<f64> = Vec::with_capacity(n);
        let mut y = 0.0;
        for _ in 0..n {
            let g = rng.gaussian();
            let x = match kind {
                NoiseKind::White => g,
                NoiseKind::Brown => {
                    y = 0.95 * y + g;
                    y
                }
                NoiseKind::Fan => unreachable!(),
            };
            v.push(x);
        }
        let p = if n == 0 {
            1.0
        } else {
            v.iter().map(|x| x * x).sum::<f64>() / n as f64
        };
        let gain = if p > 0.0 { (power_fs / p).sqrt() } else { 0.0 };
        v.iter().map(|x| x * gain * 32768.0).collect()
    }

    fn old_mix_at_snr(
        speech: &[i16],
        snr_db: f64,
        kind: NoiseKind,
        lead_s: f64,
        trail_s: f64,
        rng: &mut NoiseRng,
    ) -> Vec<i16> {
        let lead = (lead_s * 16_000.0) as usize;
        let trail = (trail_s * 16_000.0) as usize;
        let n = lead + speech.len() + trail;
        let noise_power = if snr_db.is_finite() {
            active_power(speech) / 10f64.powf(snr_db / 10.0)
        } else {
            0.0
        };
        let nz = old_noise(n, kind, noise_power, rng);
        (0..n)
            .map(|i| {
                let s = if i >= lead && i < lead + speech.len() {
                    speech[i - lead] as f64
                } else {
                    0.0
                };
                (s + nz[i]).round().clamp(-32768.0, 32767.0) as i16
            })
            .collect()
    }

    #[test]
    fn white_and_brown_noise_and_mix_at_snr_are_unchanged() {
        let speech = talker(180.0, 12000.0, 4);
        for kind in [NoiseKind::White, NoiseKind::Brown] {
            for seed in [1, 42, 2024] {
                let (mut a, mut b) = (NoiseRng::new(seed), NoiseRng::new(seed));
                assert_eq!(
                    noise(5000, kind, 3e-3, &mut a),
                    old_noise(5000, kind, 3e-3, &mut b)
                );
                for snr in [-5.0, 0.0, 7.5, 20.0, f64::INFINITY] {
                    let new = mix_at_snr(&speech, snr, kind, 0.3, 0.2, &mut a);
                    let old = old_mix_at_snr(&speech, snr, kind, 0.3, 0.2, &mut b);
                    assert_eq!(new, old, "{kind:?} seed {seed} snr {snr}");
                }
                assert_eq!(a.uniform(), b.uniform(), "the generator advanced alike");
            }
        }
    }

    #[test]
    fn room_impulse_responses_decay_at_the_requested_rt60() {
        let mut drr = Vec::new();
        for rt60 in [0.3, 0.5, 0.8] {
            for seed in [1, 2, 3, 4] {
                let h = room_impulse_response(rt60, &mut NoiseRng::new(seed));
                assert_eq!(h.len(), (rt60 * RATE).round() as usize);
                assert_eq!(h[0], 1.0);
                // Sparse before the tail: only reflections in the first 5 ms.
                let early = h[1..80].iter().filter(|&&x| x != 0.0).count();
                assert!(early <= 10, "{early} taps in the first 5 ms");
                let measured = schroeder_rt60(&h);
                assert!(
                    (measured / rt60 - 1.0).abs() < 0.15,
                    "seed {seed}: asked {rt60} s, measured {measured} s"
                );
                let reverberant: f64 = h[1..].iter().map(|x| x * x).sum();
                drr.push((rt60, db(1.0 / reverberant)));
            }
        }
        for &(rt60, d) in &drr {
            if rt60 == 0.3 {
                assert!(
                    (0.0..=6.0).contains(&d),
                    "direct-to-reverberant {d} dB at 0.3 s"
                );
            }
        }
        let mean = |rt60: f64| {
            let v: Vec<f64> = drr.iter().filter(|e| e.0 == rt60).map(|e| e.1).collect();
            v.iter().sum::<f64>() / v.len() as f64
        };
        assert!(mean(0.3) > mean(0.5) && mean(0.5) > mean(0.8), "{drr:?}");
        assert_eq!(room_impulse_response(0.0, &mut NoiseRng::new(1)), vec![1.0]);
        assert_eq!(
            room_impulse_response(f64::NAN, &mut NoiseRng::new(1)),
            vec![1.0]
        );
    }

    #[test]
    fn a_click_rings_for_about_rt60() {
        for rt60 in [0.3, 0.8] {
            let mut click = vec![0i16; 3200];
            click[1600] = 4000;
            let out = reverberate(&click, rt60, &mut NoiseRng::new(11));
            let taps = (rt60 * RATE).round() as usize;
            assert_eq!(out.len(), click.len() + taps - 1);
            assert!(
                out[..1600].iter().all(|&s| s == 0),
                "nothing before the click"
            );
            let response: Vec<f64> = out[1600..].iter().map(|&s| s as f64).collect();
            let measured = schroeder_rt60(&response);
            assert!(
                (measured / rt60 - 1.0).abs() < 0.15,
                "asked {rt60} s, measured {measured}"
            );
            // Still ringing past half the RT60, and its last 10 ms fall quiet.
            let last = response.iter().rposition(|&s| s != 0.0).unwrap_or(0);
            assert!(
                last as f64 > 0.5 * rt60 * RATE,
                "rings for {} s only",
                last as f64 / RATE
            );
            let start = power_f64(&response[160..320]);
            let end = power_f64(&response[taps - 160..taps]);
            assert!(db(end / start) < -40.0, "end {} dB", db(end / start));
        }
    }

    #[test]
    fn reverberation_keeps_the_active_power() {
        let speech = talker(170.0, 9000.0, 6);
        let input = active_power(&speech);
        for rt60 in [0.3, 0.5, 0.8] {
            let out = reverberate(&speech, rt60, &mut NoiseRng::new(3));
            let d = db(active_power(&out) / input);
            assert!(d.abs() < 1.0, "rt60 {rt60}: {d} dB");
            assert_ne!(out[..speech.len()], speech[..], "reverberant");
        }
        assert!(reverberate(&[], 0.5, &mut NoiseRng::new(3)).is_empty());
        assert!(
            reverberate(&[0; 100], 0.5, &mut NoiseRng::new(3))
                .iter()
                .all(|&s| s == 0)
        );
    }

    #[test]
    fn fft_convolution_equals_direct_convolution() {
        let mut rng = NoiseRng::new(17);
        for (na, nb) in [(300, 77), (1, 1), (64, 1), (33, 32), (5, 400)] {
            let a: Vec<f64> = (0..na).map(|_| 1000.0 * rng.gaussian()).collect();
            let b: Vec<f64> = (0..nb).map(|_| rng.gaussian()).collect();
            let mut direct = vec![0.0; na + nb - 1];
            for (i, x) in a.iter().enumerate() {
                for (j, y) in b.iter().enumerate() {
                    direct[i + j] += x * y;
                }
            }
            let fast = convolve(&a, &b);
            assert_eq!(fast.len(), direct.len());
            for (f, d) in fast.iter().zip(&direct) {
                assert!((f - d).abs() < 1e-6, "{f} vs {d}");
            }
        }
        assert!(convolve(&[], &[1.0]).is_empty());
    }

    #[test]
    fn the_same_seed_gives_the_same_output() {
        let speech = talker(190.0, 7000.0, 3);
        let talkers = vec![talker(150.0, 3000.0, 5), talker(230.0, 9000.0, 4)];
        let run = |seed| {
            let mut rng = NoiseRng::new(seed);
            (
                noise(4000, NoiseKind::Fan, 1e-3, &mut rng),
                babble(&talkers, 4000, 1e-3, &mut rng),
                room_impulse_response(0.5, &mut rng),
                reverberate(&speech, 0.4, &mut rng),
            )
        };
        assert_eq!(run(8), run(8));
        let (a, b) = (run(8), run(9));
        assert!(a.0 != b.0 && a.1 != b.1 && a.2 != b.2 && a.3 != b.3);
    }
}
