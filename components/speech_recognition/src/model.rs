//! Which acoustic model the decoders load.
//!
//! Two kinds: PocketSphinx's stock US English model (Debian `pocketsphinx-en-us`), and a copy of
//! it adapted by [`crate::adapt`] (MAP adaptation, built by the `speech_model` program) on a
//! corpus synthesized with espeak-ng or on recordings of the robot's users. The adapted model is
//! looked for in one place, [`adapted_model_dir`]; the choice is explicit on the command line
//! (`--acoustic-model stock|adapted|DIR`), or made by [`AcousticModel::resolve`] (no flag, or
//! `auto`):
//!
//! 1. `$ROBOCOG_ACOUSTIC_MODEL` (the same three forms);
//! 2. the adapted model, when [`adapted_model_dir`] holds one adapted on recordings of people;
//! 3. the stock model.
//!
//! Its provenance file says what it was adapted on ([`adapted_on`]). A model adapted on the
//! synthesized corpus knows espeak-ng's voices, not people: on voices of other synthesizer
//! families (flite's, festival's) it does worse than the stock model, by 10 to 24 points
//! (`scripts/bench speech`), so it is used only when asked for.

use pocketsphinx_sys_min::decoder::DEBIAN_MODEL_DIR;
use std::path::{Path, PathBuf};

/// The files a PocketSphinx model folder needs (`sendump` or `mixture_weights` as well).
pub const MODEL_FILES: [&str; 5] = [
    "mdef",
    "means",
    "variances",
    "transition_matrices",
    "feat.params",
];

/// Written by [`crate::adapt`] into the adapted model's folder: how it was made.
pub const PROVENANCE_FILE: &str = "robocog-model.json";

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ModelError {
    #[error(
        "acoustic model {dir}: no {file} (a PocketSphinx model folder has mdef, means, variances, transition_matrices, feat.params and sendump or mixture_weights)"
    )]
    Incomplete { dir: PathBuf, file: String },
    #[error("acoustic model {0}: no such folder")]
    Missing(PathBuf),
    #[error(
        "no adapted acoustic model at {0}: build it with `speech_model` (on the synthesized corpus) or `speech_model --recordings DIR` (on your users' recordings)"
    )]
    NotBuilt(PathBuf),
}

/// What an adapted model was adapted on (its provenance file's `corpus`), for the logs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AdaptedOn {
    /// The corpus synthesized with espeak-ng.
    Synthesized,
    /// Recordings of people.
    Recordings,
}

/// What the adapted model in `dir` was adapted on; `None` when `dir` holds no complete adapted
/// model. A model written before the provenance said (no `corpus`) was adapted on the
/// synthesized corpus.
pub fn adapted_on(dir: &Path) -> Option<AdaptedOn> {
    check_model_dir(dir).ok()?;
    if !dir.join(PROVENANCE_FILE).is_file() {
        return None;
    }
    Some(match provenance(dir, "corpus").as_deref() {
        Some("recordings") => AdaptedOn::Recordings,
        _ => AdaptedOn::Synthesized,
    })
}

/// An acoustic model folder, checked to be complete.
#[derive(Debug, Clone, PartialEq)]
pub struct AcousticModel {
    pub dir: PathBuf,
    /// Whether it is the stock Debian model (else a folder given or adapted).
    pub stock: bool,
}

/// The choice that leaves it to [`AcousticModel::resolve`], as a launch file spells it.
pub const AUTO: &str = "auto";

impl AcousticModel {
    /// The stock Debian model.
    pub fn stock() -> Self {
        Self {
            dir: stock_model_dir(),
            stock: true,
        }
    }

    /// `spec` is `stock`, `adapted` or a model folder; `None` (or `auto`, a launch file's way of
    /// naming no choice) picks as the module doc says.
    pub fn resolve(spec: Option<&str>) -> Result<Self, ModelError> {
        let env = std::env::var("ROBOCOG_ACOUSTIC_MODEL").ok();
        let spec = spec
            .filter(|s| *s != AUTO)
            .or(env.as_deref().filter(|s| !s.is_empty() && *s != AUTO));
        match spec {
            Some("stock") => Ok(Self::stock()),
            Some("adapted") => Self::at(&adapted_model_dir()).map_err(|e| match e {
                ModelError::Missing(dir) => ModelError::NotBuilt(dir),
                e => e,
            }),
            Some(dir) => Self::at(Path::new(dir)),
            None => {
                let adapted = adapted_model_dir();
                if adapted_on(&adapted) == Some(AdaptedOn::Recordings) {
                    Self::at(&adapted)
                } else {
                    Ok(Self::stock())
                }
            }
        }
    }

    /// What [`Self::resolve`] picks without a command-line choice, in the form it takes:
    /// `stock`, `adapted`, or the folder `$ROBOCOG_ACOUSTIC_MODEL` names.
    pub fn default_spec() -> String {
        match Self::resolve(None) {
            Ok(m) if m.stock => "stock".into(),
            Ok(m) if m.dir == adapted_model_dir() => "adapted".into(),
            Ok(m) => m.dir.display().to_string(),
            Err(_) => "stock".into(),
        }
    }

    /// What [`Self::resolve`] picks without a command-line choice; when that fails (a broken
    /// `$ROBOCOG_ACOUSTIC_MODEL`), the stock model, with a warning in the log.
    pub fn preferred() -> Self {
        Self::resolve(None).unwrap_or_else(|e| {
            tracing::warn!("{e}; using the stock acoustic model");
            Self::stock()
        })
    }

    /// The model in `dir`, if it is complete.
    pub fn at(dir: &Path) -> Result<Self, ModelError> {
        check_model_dir(dir)?;
        let stock = dir == stock_model_dir();
        Ok(Self {
            dir: dir.to_path_buf(),
            stock,
        })
    }

    /// A line for the logs: which model, and how it was made when known.
    pub fn describe(&self) -> String {
        if self.stock {
            return format!("stock PocketSphinx en-us ({})", self.dir.display());
        }
        let how = provenance(&self.dir, "summary").unwrap_or_else(|| "no provenance file".into());
        format!("{} ({how})", self.dir.display())
    }
}

/// A text field of the provenance file in `dir`, if there is one.
pub fn provenance(dir: &Path, field: &str) -> Option<String> {
    let text = std::fs::read_to_string(dir.join(PROVENANCE_FILE)).ok()?;
    let v: serde_json::Value = serde_json::from_str(&text).ok()?;
    v.get(field)?.as_str().map(String::from)
}

/// The stock model's folder.
pub fn stock_model_dir() -> PathBuf {
    Path::new(DEBIAN_MODEL_DIR).join("en-us")
}

/// Where `speech_model` writes the adapted model and the recognizer looks for it:
/// `$XDG_CACHE_HOME/robocog/speech/en-us-adapted`, else under `~/.cache`. A cache: it is
/// rebuilt from the recipe in [`crate::adapt`] when missing or out of date.
pub fn adapted_model_dir() -> PathBuf {
    let cache = std::env::var_os("XDG_CACHE_HOME")
        .filter(|v| !v.is_empty())
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))
        .unwrap_or_else(std::env::temp_dir);
    cache.join("robocog/speech/en-us-adapted")
}

/// Whether `dir` holds every file of a PocketSphinx model.
pub fn check_model_dir(dir: &Path) -> Result<(), ModelError> {
    if !dir.is_dir() {
        return Err(ModelError::Missing(dir.to_path_buf()));
    }
    for f in MODEL_FILES {
        if !dir.join(f).is_file() {
            return Err(ModelError::Incomplete {
                dir: dir.to_path_buf(),
                file: f.into(),
            });
        }
    }
    if !dir.join("sendump").is_file() && !dir.join("mixture_weights").is_file() {
        return Err(ModelError::Incomplete {
            dir: dir.to_path_buf(),
            file: "sendump or mixture_weights".into(),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stock_model_is_complete_and_named() {
        let m = AcousticModel::resolve(Some("stock")).unwrap();
        assert!(m.stock);
        check_model_dir(&m.dir).unwrap();
        assert!(m.describe().contains("stock"));
    }

    #[test]
    fn an_incomplete_folder_is_a_clear_error() {
        let d = std::env::temp_dir().join(format!("robocog-model-test-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        std::fs::write(d.join("mdef"), b"x").unwrap();
        let e = AcousticModel::resolve(Some(d.to_str().unwrap())).unwrap_err();
        assert!(
            matches!(&e, ModelError::Incomplete { file, .. } if file == "means"),
            "{e}"
        );
        assert!(e.to_string().contains("means"));
        std::fs::remove_dir_all(&d).unwrap();
        let e = AcousticModel::resolve(Some(d.to_str().unwrap())).unwrap_err();
        assert_eq!(e, ModelError::Missing(d));
    }

    /// What a model was adapted on is read from its provenance; a model from before the
    /// provenance said is the synthesized one; an incomplete folder is no model.
    #[test]
    fn what_a_model_was_adapted_on_is_read_from_its_provenance() {
        let d = std::env::temp_dir().join(format!("robocog-model-on-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        for f in MODEL_FILES.iter().chain(&["sendump"]) {
            std::fs::write(d.join(f), b"x").unwrap();
        }
        assert_eq!(adapted_on(&d), None, "no provenance: not an adapted model");
        let prov = d.join(PROVENANCE_FILE);
        std::fs::write(&prov, r#"{"recipe": "1", "summary": "old"}"#).unwrap();
        assert_eq!(adapted_on(&d), Some(AdaptedOn::Synthesized));
        std::fs::write(&prov, r#"{"recipe": "1", "corpus": "synthesized"}"#).unwrap();
        assert_eq!(adapted_on(&d), Some(AdaptedOn::Synthesized));
        std::fs::write(&prov, r#"{"recipe": "1", "corpus": "recordings"}"#).unwrap();
        assert_eq!(adapted_on(&d), Some(AdaptedOn::Recordings));
        // Each kind of model is judged with the confidence calibration fitted for its kind.
        use crate::confidence::ConfidenceConfig;
        let adapted = AcousticModel::at(&d).unwrap();
        assert_eq!(
            ConfidenceConfig::for_model(&adapted),
            ConfidenceConfig::ADAPTED
        );
        assert_eq!(
            ConfidenceConfig::for_model(&AcousticModel::stock()),
            ConfidenceConfig::STOCK
        );
        assert_ne!(ConfidenceConfig::STOCK, ConfidenceConfig::ADAPTED);
        std::fs::remove_file(d.join(PROVENANCE_FILE)).unwrap();
        let unknown = AcousticModel::at(&d).unwrap();
        assert_eq!(
            ConfidenceConfig::for_model(&unknown),
            ConfidenceConfig::STOCK,
            "a model of unknown making is judged as the stock one"
        );
        std::fs::remove_file(d.join("means")).unwrap();
        assert_eq!(adapted_on(&d), None, "an incomplete folder is no model");
        std::fs::remove_dir_all(&d).unwrap();
    }
}
