//! The model files the recipe reads and checks: `feat.params`, and the mixture weights of a
//! `sendump` file.

use super::*;

/// The options of a model's `feat.params` that SphinxTrain needs too.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct FeatParams {
    pub(super) feat: String,
    pub(super) svspec: String,
    pub(super) cmn: String,
    pub(super) agc: String,
    pub(super) model: String,
}

impl FeatParams {
    pub(super) fn read(path: &Path) -> Result<Self, AdaptError> {
        let text = std::fs::read_to_string(path).map_err(|e| file_err(path, e))?;
        Ok(Self::parse(&text))
    }

    pub(super) fn parse(text: &str) -> Self {
        let get = |k: &str, default: &str| {
            let mut it = text.split_whitespace();
            while let Some(w) = it.next() {
                if w == k {
                    return it.next().unwrap_or(default).to_string();
                }
            }
            default.to_string()
        };
        Self {
            feat: get("-feat", "1s_c_d_dd"),
            svspec: get("-svspec", ""),
            cmn: get("-cmn", "current"),
            agc: get("-agc", "none"),
            model: get("-model", "ptm"),
        }
    }

    /// The tied-state-to-codebook mapping of the model type.
    pub(super) fn ts2cb(&self) -> &'static str {
        match self.model.as_str() {
            "ptm" => ".ptm.",
            "semi" => ".semi.",
            _ => ".cont.",
        }
    }
}

/// Mixture weights, `[senone][stream][density]`, each row summing to 1.
#[derive(Debug, Clone, PartialEq)]
pub struct MixtureWeights {
    pub n_senones: usize,
    pub n_streams: usize,
    pub n_densities: usize,
    pub weights: Vec<f32>,
}

/// One unit of a `sendump` value: PocketSphinx stores `-log(w)` in its log base 1.0001, shifted
/// right by 10 bits (`SENSCR_SHIFT`), in one byte.
pub const SENDUMP_UNIT_LN: f64 = 1024.0 * 0.000_099_995_000_333_308_3; // 1024 · ln(1.0001)

/// Recover the mixture weights from a PocketSphinx `sendump` (8-bit, the layout of the stock
/// model): a header of length-prefixed strings ending with an empty one, the row and column
/// counts when there is no clustering, then `[stream][density][senone]` bytes.
pub fn sendump_to_mixture_weights(bytes: &[u8]) -> Result<MixtureWeights, String> {
    let mut p = 0usize;
    let int = |p: &mut usize| -> Result<i32, String> {
        let b = bytes
            .get(*p..*p + 4)
            .ok_or_else(|| format!("truncated at byte {p}"))?;
        *p += 4;
        Ok(i32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    let (mut n_streams, mut clusters, mut bits) = (0usize, 0usize, 8usize);
    loop {
        let n = int(&mut p)?;
        if n == 0 {
            break;
        }
        if !(1..=1000).contains(&n) {
            return Err(format!(
                "header string of length {n} (not a little-endian sendump)"
            ));
        }
        let s = bytes
            .get(p..p + n as usize)
            .ok_or_else(|| "truncated header".to_string())?;
        p += n as usize;
        let s = String::from_utf8_lossy(s);
        let s = s.trim_end_matches('\0');
        let val = |k: &str| {
            s.strip_prefix(k)
                .and_then(|v| v.trim().parse::<usize>().ok())
        };
        if let Some(v) = val("feature_count ") {
            n_streams = v;
        } else if let Some(v) = val("cluster_count ") {
            clusters = v;
        } else if let Some(v) = val("cluster_bits ") {
            bits = v;
        }
    }
    if clusters != 0 || bits != 8 {
        return Err(format!(
            "clustered or {bits}-bit sendump (cluster_count {clusters}): only 8-bit unclustered ones are read"
        ));
    }
    if n_streams == 0 {
        return Err("no feature_count in the header".into());
    }
    let rows = int(&mut p)?;
    let cols = int(&mut p)?;
    if rows <= 0 || cols <= 0 {
        return Err(format!("{rows} densities by {cols} senones"));
    }
    let (n_densities, n_senones) = (rows as usize, cols as usize);
    let data = &bytes[p..];
    let need = n_streams * n_densities * n_senones;
    if data.len() != need {
        return Err(format!(
            "{} bytes of weights, {need} expected ({n_streams} streams x {n_densities} densities x {n_senones} senones)",
            data.len()
        ));
    }
    let mut weights = vec![0f32; need];
    for f in 0..n_streams {
        for d in 0..n_densities {
            let row = &data[(f * n_densities + d) * n_senones..][..n_senones];
            for (s, &v) in row.iter().enumerate() {
                weights[(s * n_streams + f) * n_densities + d] =
                    (-(v as f64) * SENDUMP_UNIT_LN).exp() as f32;
            }
        }
    }
    for row in weights.chunks_mut(n_densities) {
        let sum: f32 = row.iter().sum();
        if sum > 0.0 {
            row.iter_mut().for_each(|w| *w /= sum);
        }
    }
    Ok(MixtureWeights {
        n_senones,
        n_streams,
        n_densities,
        weights,
    })
}

impl MixtureWeights {
    /// SphinxTrain's binary `mixture_weights` file (no checksum).
    pub fn to_s3_bytes(&self) -> Vec<u8> {
        let mut v = b"s3\nversion 1.0\nendhdr\n".to_vec();
        v.extend(0x1122_3344u32.to_le_bytes());
        for n in [
            self.n_senones,
            self.n_streams,
            self.n_densities,
            self.weights.len(),
        ] {
            v.extend((n as u32).to_le_bytes());
        }
        for w in &self.weights {
            v.extend(w.to_le_bytes());
        }
        v
    }
}
