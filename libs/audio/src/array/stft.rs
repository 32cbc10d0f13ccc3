//! Streaming short-time Fourier analysis of an array's channels and overlap-add synthesis of one
//! channel: 512-sample frames every 256 samples, a square-root Hann window on both sides (their
//! product, a Hann window, sums to exactly 1 at 50 % overlap), so that a chunk of any size gives
//! as many output samples, [`Synthesizer::LATENCY`] late.

use std::{collections::VecDeque, sync::Arc};

use rustfft::{Fft, FftPlanner, num_complex::Complex};

use super::{ArrayError, ArrayGeometry, Multichannel};

/// Samples in a frame.
pub(crate) const FRAME: usize = 512;
/// Samples between two frames.
pub(crate) const HOP: usize = FRAME / 2;
/// The bins of a real frame's spectrum that matter (0 to Nyquist).
pub(crate) const BINS: usize = FRAME / 2 + 1;

/// The square root of a periodic Hann window of [`FRAME`] samples.
fn sqrt_hann() -> Vec<f64> {
    (0..FRAME)
        .map(|n| {
            let phase = 2.0 * std::f64::consts::PI * n as f64 / FRAME as f64;
            (0.5 - 0.5 * phase.cos()).sqrt()
        })
        .collect()
}

/// Cuts the channels of a stream into windowed frames and transforms them.
#[derive(Clone)]
pub(crate) struct Analyzer {
    geometry: ArrayGeometry,
    fft: Arc<dyn Fft<f64>>,
    window: Vec<f64>,
    /// The last [`FRAME`] samples of each channel, of which the last [`HOP`] are being filled.
    history: Vec<Vec<f64>>,
    /// How many of the last [`HOP`] samples of `history` are filled.
    filled: usize,
    /// The input being pushed, per channel.
    decoded: Vec<Vec<f64>>,
    /// The spectrum of the last frame, per channel ([`FRAME`] bins, the first [`BINS`] used).
    spectra: Vec<Vec<Complex<f64>>>,
    scratch: Vec<Complex<f64>>,
}

impl Analyzer {
    pub(crate) fn new(geometry: &ArrayGeometry) -> Self {
        let fft = FftPlanner::new().plan_fft_forward(FRAME);
        let channels = geometry.channels();
        Self {
            geometry: geometry.clone(),
            scratch: vec![Complex::default(); fft.get_inplace_scratch_len()],
            fft,
            window: sqrt_hann(),
            history: vec![vec![0.0; FRAME]; channels],
            filled: 0,
            decoded: vec![Vec::new(); channels],
            spectra: vec![vec![Complex::default(); FRAME]; channels],
        }
    }

    pub(crate) fn geometry(&self) -> &ArrayGeometry {
        &self.geometry
    }

    /// Feeds `input` in, calling `on_frame` with the spectra of each frame it completes (one per
    /// channel, of which bins `0..BINS` matter). Returns the number of samples per channel of
    /// `input`. Bad input is refused whole, leaving the stream as it was.
    pub(crate) fn push(
        &mut self,
        input: Multichannel<'_>,
        mut on_frame: impl FnMut(&[Vec<Complex<f64>>]),
    ) -> Result<usize, ArrayError> {
        let n = self.decode(input)?;
        let mut done = 0;
        while done < n {
            let take = (HOP - self.filled).min(n - done);
            let at = FRAME - HOP + self.filled;
            for (history, decoded) in self.history.iter_mut().zip(&self.decoded) {
                history[at..at + take].copy_from_slice(&decoded[done..done + take]);
            }
            self.filled += take;
            done += take;
            if self.filled == HOP {
                self.transform();
                on_frame(&self.spectra);
                for history in &mut self.history {
                    history.copy_within(HOP.., 0);
                }
                self.filled = 0;
            }
        }
        Ok(n)
    }

    fn transform(&mut self) {
        for (spectrum, history) in self.spectra.iter_mut().zip(&self.history) {
            for ((s, &x), &w) in spectrum.iter_mut().zip(history).zip(&self.window) {
                *s = Complex::new(x * w, 0.0);
            }
            self.fft.process_with_scratch(spectrum, &mut self.scratch);
        }
    }

    /// `input` checked and copied into `decoded`; the number of samples per channel.
    fn decode(&mut self, input: Multichannel<'_>) -> Result<usize, ArrayError> {
        let channels = self.decoded.len();
        match input {
            Multichannel::Interleaved(samples) => {
                if samples.len() % channels != 0 {
                    return Err(ArrayError::PartialFrame {
                        len: samples.len(),
                        channels,
                    });
                }
                for (c, decoded) in self.decoded.iter_mut().enumerate() {
                    decoded.clear();
                    decoded.extend(
                        samples
                            .iter()
                            .skip(c)
                            .step_by(channels)
                            .map(|&s| f64::from(s)),
                    );
                }
                Ok(samples.len() / channels)
            }
            Multichannel::Planar(slices) => {
                self.geometry.check_channels(slices.len())?;
                let expected = slices.first().map_or(0, |s| s.len());
                for (channel, slice) in slices.iter().enumerate() {
                    if slice.len() != expected {
                        return Err(ArrayError::RaggedChannels {
                            channel,
                            len: slice.len(),
                            expected,
                        });
                    }
                    if let Some(index) = slice.iter().position(|x| !x.is_finite()) {
                        return Err(ArrayError::NonFiniteSample { channel, index });
                    }
                }
                for (decoded, slice) in self.decoded.iter_mut().zip(slices) {
                    decoded.clear();
                    decoded.extend(slice.iter().map(|&x| f64::from(x)));
                }
                Ok(expected)
            }
        }
    }
}

/// Turns the spectra of successive frames back into a stream by overlap-add, [`Self::LATENCY`]
/// samples late.
#[derive(Clone)]
pub(crate) struct Synthesizer {
    ifft: Arc<dyn Fft<f64>>,
    window: Vec<f64>,
    /// The spectrum of the next frame ([`FRAME`] bins; the caller fills the first [`BINS`]).
    spectrum: Vec<Complex<f64>>,
    scratch: Vec<Complex<f64>>,
    /// The sum of the frames' windowed outputs over the samples of the last frame.
    overlap: Vec<f64>,
    /// Finished samples not yet given out.
    pending: VecDeque<f64>,
}

impl Synthesizer {
    /// How late the output is (samples): the first sample of a hop's output needs the frame that
    /// ends [`FRAME`] - 1 samples later, whatever the chunk sizes.
    pub(crate) const LATENCY: usize = FRAME - 1;

    pub(crate) fn new() -> Self {
        let ifft = FftPlanner::new().plan_fft_inverse(FRAME);
        Self {
            scratch: vec![Complex::default(); ifft.get_inplace_scratch_len()],
            ifft,
            window: sqrt_hann(),
            spectrum: vec![Complex::default(); FRAME],
            overlap: vec![0.0; FRAME],
            // The frames complete HOP samples of output each, the first one the HOP samples
            // FRAME - HOP before the input's start: these zeros bring that to LATENCY.
            pending: VecDeque::from(vec![0.0; Self::LATENCY - (FRAME - HOP)]),
        }
    }

    /// Bins `0..BINS` of the next frame's spectrum, to fill (the rest follows by symmetry).
    pub(crate) fn half_spectrum_mut(&mut self) -> &mut [Complex<f64>] {
        &mut self.spectrum[..BINS]
    }

    /// Adds the frame whose spectrum was filled to the output.
    pub(crate) fn finish_frame(&mut self) {
        let half = FRAME / 2;
        self.spectrum[0].im = 0.0;
        self.spectrum[half].im = 0.0;
        for k in 1..half {
            self.spectrum[FRAME - k] = self.spectrum[k].conj();
        }
        self.ifft
            .process_with_scratch(&mut self.spectrum, &mut self.scratch);
        let scale = 1.0 / FRAME as f64;
        for ((o, s), &w) in self
            .overlap
            .iter_mut()
            .zip(&self.spectrum)
            .zip(&self.window)
        {
            *o += s.re * scale * w;
        }
        self.pending.extend(&self.overlap[..HOP]);
        self.overlap.copy_within(HOP.., 0);
        self.overlap[FRAME - HOP..].fill(0.0);
    }

    /// The next `n` samples of output, into `out` (cleared first).
    fn drain(&mut self, n: usize, out: &mut Vec<f32>) {
        out.clear();
        // After r samples in, floor(r / HOP) frames gave HOP samples each on top of the
        // HOP - 1 zeros, which is at least r: the pending samples always suffice.
        out.extend(self.pending.drain(..n).map(|y| y as f32));
    }
}

/// An [`Analyzer`] and a [`Synthesizer`] with a beamformer between them.
#[derive(Clone)]
pub(crate) struct StftStream {
    analyzer: Analyzer,
    synthesizer: Synthesizer,
}

impl StftStream {
    pub(crate) fn new(geometry: &ArrayGeometry) -> Self {
        Self {
            analyzer: Analyzer::new(geometry),
            synthesizer: Synthesizer::new(),
        }
    }

    pub(crate) fn geometry(&self) -> &ArrayGeometry {
        self.analyzer.geometry()
    }

    /// Feeds `input` in; for each frame completed, `beam` gets the channels' spectra and fills
    /// bins `0..BINS` of the output spectrum. `out` gets as many samples as `input` has per
    /// channel.
    pub(crate) fn process(
        &mut self,
        input: Multichannel<'_>,
        out: &mut Vec<f32>,
        mut beam: impl FnMut(&[Vec<Complex<f64>>], &mut [Complex<f64>]),
    ) -> Result<(), ArrayError> {
        let Self {
            analyzer,
            synthesizer,
        } = self;
        let n = analyzer.push(input, |spectra| {
            beam(spectra, synthesizer.half_spectrum_mut());
            synthesizer.finish_frame();
        })?;
        synthesizer.drain(n, out);
        Ok(())
    }
}
