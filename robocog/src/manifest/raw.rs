//! The manifest files as written: the TOML's shape (unknown keys refused), reading a file and
//! the files it includes, and `${name}` substitution.

use super::{Origin, Problem, RestartPolicy};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use toml::Spanned;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawManifest {
    #[serde(default)]
    pub(super) include: Vec<Spanned<String>>,
    #[serde(default)]
    pub(super) graph: RawGraph,
    #[serde(default)]
    pub(super) vars: BTreeMap<String, String>,
    #[serde(default)]
    pub(super) profiles: BTreeMap<String, BTreeMap<String, String>>,
    #[serde(default)]
    pub(super) machines: BTreeMap<String, Spanned<RawMachine>>,
    #[serde(default)]
    pub(super) component: Vec<RawComponent>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawMachine {
    pub(super) router: String,
}

#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub(super) struct RawGraph {
    pub(super) name: Option<String>,
    pub(super) namespace: Option<String>,
    pub(super) router: Option<String>,
    pub(super) certs: Option<String>,
    pub(super) insecure_bus: Option<bool>,
}

fn default_true() -> bool {
    true
}
fn default_max_restarts() -> u32 {
    5
}
fn default_backoff_ms() -> u64 {
    500
}
fn default_ready_timeout_s() -> f64 {
    15.0
}
fn default_stop_timeout_s() -> f64 {
    5.0
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawComponent {
    pub(super) name: Spanned<String>,
    pub(super) binary: Option<Spanned<String>>,
    pub(super) python: Option<Spanned<String>>,
    #[serde(default)]
    pub(super) args: Vec<String>,
    #[serde(default)]
    pub(super) env: BTreeMap<String, String>,
    #[serde(default)]
    pub(super) depends_on: Vec<Spanned<String>>,
    #[serde(default)]
    pub(super) restart: RestartPolicy,
    #[serde(default = "default_max_restarts")]
    pub(super) max_restarts: u32,
    #[serde(default = "default_backoff_ms")]
    pub(super) backoff_ms: u64,
    #[serde(default = "default_true")]
    pub(super) required: bool,
    #[serde(default = "default_ready_timeout_s")]
    pub(super) ready_timeout_s: f64,
    #[serde(default = "default_stop_timeout_s")]
    pub(super) stop_timeout_s: f64,
    #[serde(default)]
    pub(super) hardware: Vec<Spanned<String>>,
    #[serde(default)]
    pub(super) completes_graph: bool,
    #[serde(default)]
    pub(super) external_inputs: Vec<String>,
    pub(super) enabled: Option<Spanned<String>>,
    pub(super) machine: Option<Spanned<String>>,
}

pub(super) fn line_of(src: &str, offset: usize) -> usize {
    src[..offset.min(src.len())]
        .bytes()
        .filter(|&b| b == b'\n')
        .count()
        + 1
}

pub(super) struct Loaded {
    pub(super) file: PathBuf,
    pub(super) src: String,
    pub(super) raw: RawManifest,
}

/// The largest manifest file read (a graph's manifest is a few kilobytes).
const MAX_MANIFEST_BYTES: u64 = 1 << 20;

/// A manifest's text: a regular file of at most [`MAX_MANIFEST_BYTES`] (an include naming a
/// device, a FIFO or a huge file is refused before it is read).
fn read_manifest_file(path: &Path) -> std::io::Result<String> {
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "not a regular file",
        ));
    }
    if meta.len() > MAX_MANIFEST_BYTES {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!(
                "{} bytes, more than a manifest's {MAX_MANIFEST_BYTES}",
                meta.len()
            ),
        ));
    }
    std::fs::read_to_string(path)
}

pub(super) fn load_tree(
    path: &Path,
    stack: &mut Vec<PathBuf>,
    out: &mut Vec<Loaded>,
    problems: &mut Vec<Problem>,
    from: Option<Origin>,
) {
    let at = |line| Origin {
        file: path.to_path_buf(),
        line,
    };
    let src = match read_manifest_file(path) {
        Ok(s) => s,
        Err(e) => {
            let origin = from.unwrap_or_else(|| at(0));
            problems.push(Problem {
                origin,
                message: format!("cannot read {}: {e}", path.display()),
            });
            return;
        }
    };
    let canonical = path.canonicalize().unwrap_or_else(|_| path.to_path_buf());
    if stack.contains(&canonical) {
        let origin = from.unwrap_or_else(|| at(0));
        problems.push(Problem {
            origin,
            message: format!("include cycle through {}", path.display()),
        });
        return;
    }
    let raw: RawManifest = match toml::from_str(&src) {
        Ok(r) => r,
        Err(e) => {
            let line = e.span().map_or(0, |s| line_of(&src, s.start));
            problems.push(Problem {
                origin: at(line),
                message: e.message().trim().to_string(),
            });
            return;
        }
    };
    stack.push(canonical);
    let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    for inc in &raw.include {
        let child = dir.join(inc.get_ref());
        let origin = at(line_of(&src, inc.span().start));
        load_tree(&child, stack, out, problems, Some(origin));
    }
    stack.pop();
    out.push(Loaded {
        file: path.to_path_buf(),
        src,
        raw,
    });
}

pub(super) fn substitute(s: &str, vars: &BTreeMap<String, String>) -> Result<String, String> {
    let mut out = String::with_capacity(s.len());
    let mut rest = s;
    while let Some(i) = rest.find("${") {
        out.push_str(&rest[..i]);
        let after = &rest[i + 2..];
        let end = after
            .find('}')
            .ok_or_else(|| format!("unclosed ${{ in {s:?}"))?;
        let name = &after[..end];
        let value = vars.get(name).ok_or_else(|| {
            let known: Vec<&str> = vars.keys().map(String::as_str).collect();
            format!("unknown variable ${{{name}}} (known: {})", known.join(", "))
        })?;
        out.push_str(value);
        rest = &after[end + 1..];
    }
    out.push_str(rest);
    Ok(out)
}
