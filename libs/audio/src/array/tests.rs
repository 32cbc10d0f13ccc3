//! Tests of the microphone-array module, on simulated plane waves; the helpers they share.

use super::sim::render_plane_wave;
use super::*;
use crate::signal::{NoiseKind, NoiseRng, noise};

mod beamformer;
mod geometry;
mod srp;

const RATE: usize = 16_000;

/// `n` samples of white noise of `power_fs` (full-scale units), in sample units.
fn white(n: usize, power_fs: f64, seed: u64) -> Vec<f64> {
    noise(n, NoiseKind::White, power_fs, &mut NoiseRng::new(seed))
}

/// The channels of `geometry` for `mono` arriving from `azimuth_deg` in the horizontal plane.
fn from_azimuth(geometry: &ArrayGeometry, mono: &[f64], azimuth_deg: f64) -> Vec<Vec<f64>> {
    render_plane_wave(
        geometry,
        mono,
        direction(azimuth_deg.to_radians(), 0.0),
        RATE as f64,
    )
    .unwrap()
}

/// Channel-wise sum.
fn mix(a: &[Vec<f64>], b: &[Vec<f64>]) -> Vec<Vec<f64>> {
    a.iter()
        .zip(b)
        .map(|(a, b)| a.iter().zip(b).map(|(a, b)| a + b).collect())
        .collect()
}

/// Independent white noise on each of `channels` channels (a sensor's or a diffuse noise).
fn uncorrelated(channels: usize, n: usize, power_fs: f64, seed: u64) -> Vec<Vec<f64>> {
    (0..channels)
        .map(|c| white(n, power_fs, seed * 100 + c as u64))
        .collect()
}

fn as_f32(channels: &[Vec<f64>]) -> Vec<Vec<f32>> {
    channels
        .iter()
        .map(|c| c.iter().map(|&x| x as f32).collect())
        .collect()
}

/// Mean square.
fn power<T: Copy + Into<f64>>(x: &[T]) -> f64 {
    x.iter().map(|&v| v.into().powi(2)).sum::<f64>() / x.len().max(1) as f64
}

fn db(ratio: f64) -> f64 {
    10.0 * ratio.log10()
}
