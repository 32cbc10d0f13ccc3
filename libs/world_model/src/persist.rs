//! Persistence of the live graph in a state folder: a snapshot plus an append-only change log,
//! so that a restarted service recovers its state with nothing lost.
//!
//! ## Files (in the state folder)
//!
//! | file | holds |
//! |---|---|
//! | `snapshot.json` | the newest snapshot: `{"format":"robocog-dr-state","version":2,"last_seq":N,"snapshot":{..}}` (the library's [`Snapshot`] plus the sequence number of the last change it includes) |
//! | `snapshot.prev.json` | the snapshot before it (the fallback when the newest is corrupt) |
//! | `changes.log` | one JSON line per change since `snapshot.json`: `{"seq":N,"event":{..ChangeEvent..}}`, or `{"seq":N,"restore":{..Snapshot..}}` when the whole graph was replaced |
//! | `changes.prev.log` | the change lines since `snapshot.prev.json` (so the fallback loses nothing) |
//! | `*.corrupt` | a snapshot that failed to load, set aside for inspection |
//!
//! ## Writes
//!
//! Every batch of changes is appended with one `write` call on an unbuffered file before the
//! service replies, so it survives a crash or a SIGKILL of the process (the kernel holds it); with
//! [`StoreOptions::fsync`] each batch is also `fdatasync`ed, which survives a power loss at the cost
//! of a disk flush per change. Every [`StoreOptions::compact_every`] changes (and at start and
//! clean stop) the store compacts: it writes the graph to `snapshot.json.tmp` (fsync), renames
//! `snapshot.json` to `snapshot.prev.json` and `changes.log` to `changes.prev.log`, renames the
//! temporary file to `snapshot.json` and starts an empty `changes.log`. A crash at any step
//! leaves a state that recovers completely: change lines carry sequence numbers and recovery
//! skips those a snapshot already includes.
//!
//! ## Recovery ([`Store::open`])
//!
//! Load `snapshot.json`, or if it is missing or corrupt (bad JSON, a wrong format, an
//! inconsistent graph) `snapshot.prev.json`; each corrupt file is reported (its path and the
//! parse error) and renamed to `*.corrupt`. Then replay `changes.prev.log` and `changes.log` in
//! order, skipping lines whose sequence number the snapshot includes. A line that is not valid
//! JSON (a torn last write, a damaged disk) is reported with its file and line number, counted
//! and skipped; an event that no longer applies is reported and counted. With no snapshot at all
//! and no log, the caller's start scene is used. The outcome is a [`RecoveryReport`].

use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::DrError;
use crate::graph::{SNAPSHOT_VERSION, SceneGraph};
use crate::types::{ChangeEvent, Snapshot};

/// The newest snapshot.
pub const SNAPSHOT_FILE: &str = "snapshot.json";
/// The snapshot before it.
pub const PREV_SNAPSHOT_FILE: &str = "snapshot.prev.json";
/// Changes since [`SNAPSHOT_FILE`].
pub const LOG_FILE: &str = "changes.log";
/// Changes since [`PREV_SNAPSHOT_FILE`] up to [`SNAPSHOT_FILE`].
pub const PREV_LOG_FILE: &str = "changes.prev.log";
/// Format tag of the snapshot files.
pub const STATE_FORMAT: &str = "robocog-dr-state";

/// A snapshot file: the graph and the last change sequence number it includes.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StateFile {
    /// Always [`STATE_FORMAT`].
    pub format: String,
    /// [`SNAPSHOT_VERSION`] (files of the first format have none).
    #[serde(default)]
    pub version: u32,
    /// Sequence number of the newest change included.
    pub last_seq: u64,
    /// The graph.
    pub snapshot: Snapshot,
}

/// One line of the change log: a change event, or a whole-graph replacement.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LogLine {
    /// Sequence number (strictly increasing over the life of the state folder).
    pub seq: u64,
    /// The change.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub event: Option<ChangeEvent>,
    /// The graph was replaced by this snapshot.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub restore: Option<Snapshot>,
}

/// How the store writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StoreOptions {
    /// Compact after this many changes (at least 1).
    pub compact_every: usize,
    /// `fdatasync` the log after every batch.
    pub fsync: bool,
}

impl Default for StoreOptions {
    fn default() -> Self {
        Self {
            compact_every: 1000,
            fsync: false,
        }
    }
}

/// Errors of the store (the state folder cannot be written, or the start scene failed).
#[derive(Debug, thiserror::Error)]
pub enum PersistError {
    /// A file of the state folder could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The start scene could not be built.
    #[error("cannot build the start scene: {0}")]
    Scene(#[source] DrError),
    /// A state that cannot be written as JSON (cannot happen with finite graphs).
    #[error("cannot encode the state: {0}")]
    Encode(#[from] serde_json::Error),
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> PersistError + '_ {
    move |source| PersistError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// What recovery found and did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RecoveryReport {
    /// The snapshot file loaded (`None`: the start scene was used).
    pub snapshot: Option<PathBuf>,
    /// Snapshot files that failed to load.
    pub corrupt_snapshots: usize,
    /// Change lines applied.
    pub replayed: usize,
    /// Change lines skipped because the snapshot already includes them.
    pub already_included: usize,
    /// Lines that are not valid JSON change lines (skipped).
    pub bad_lines: usize,
    /// Valid lines whose change no longer applies (skipped).
    pub failed_events: usize,
    /// Sequence number of the newest change recovered.
    pub last_seq: u64,
    /// Every problem, one line each, naming the file (and line) and the error.
    pub problems: Vec<String>,
}

impl RecoveryReport {
    /// Whether the state folder held nothing: the start scene is in use.
    pub fn is_fresh(&self) -> bool {
        self.snapshot.is_none() && self.replayed == 0
    }
}

/// The state folder of a running service.
#[derive(Debug)]
pub struct Store {
    dir: PathBuf,
    log: File,
    options: StoreOptions,
    since_compaction: usize,
}

fn load_state(path: &Path) -> Result<(SceneGraph, u64), String> {
    let text = std::fs::read_to_string(path).map_err(|e| e.to_string())?;
    #[derive(Deserialize)]
    struct Head {
        #[serde(default)]
        format: String,
        #[serde(default)]
        version: u32,
    }
    let head: Head =
        serde_json::from_str(&text).map_err(|e| format!("not a valid state file: {e}"))?;
    if head.format != STATE_FORMAT {
        return Err(format!(
            "format is `{}`, expected `{STATE_FORMAT}`",
            head.format
        ));
    }
    if head.version != SNAPSHOT_VERSION {
        return Err(format!(
            "version {} (expected {SNAPSHOT_VERSION}): {}",
            head.version,
            if head.version < SNAPSHOT_VERSION {
                "written by an older robocog, whose DR types differed; set aside, the DR starts \
                 from its scene"
            } else {
                "written by a newer robocog"
            }
        ));
    }
    let state: StateFile =
        serde_json::from_str(&text).map_err(|e| format!("not a valid state file: {e}"))?;
    let g = SceneGraph::restore(&state.snapshot).map_err(|e| e.to_string())?;
    Ok((g, state.last_seq))
}

impl Store {
    /// Opens (creating it if needed) the state folder `dir` and recovers the graph, or builds it
    /// with `start_scene` when the folder holds no state; then compacts, so the folder holds a
    /// fresh snapshot and an empty log. The graph's change log is left off.
    pub fn open(
        dir: &Path,
        options: StoreOptions,
        start_scene: impl FnOnce() -> crate::Result<SceneGraph>,
    ) -> Result<(Store, SceneGraph, RecoveryReport), PersistError> {
        std::fs::create_dir_all(dir).map_err(io_err(dir))?;
        let mut report = RecoveryReport::default();
        let mut base = None;
        for name in [SNAPSHOT_FILE, PREV_SNAPSHOT_FILE] {
            let path = dir.join(name);
            if !path.exists() {
                continue;
            }
            match load_state(&path) {
                Ok((g, seq)) => {
                    base = Some((g, seq));
                    report.snapshot = Some(path);
                    break;
                }
                Err(e) => {
                    report.corrupt_snapshots += 1;
                    let aside = dir.join(format!("{name}.corrupt"));
                    let kept = match std::fs::rename(&path, &aside) {
                        Ok(()) => format!(" (kept as {})", aside.display()),
                        Err(re) => format!(" (could not set it aside: {re})"),
                    };
                    report
                        .problems
                        .push(format!("corrupt snapshot {}: {e}{kept}", path.display()));
                }
            }
        }
        let logs: Vec<PathBuf> = [PREV_LOG_FILE, LOG_FILE]
            .iter()
            .map(|n| dir.join(n))
            .filter(|p| p.exists())
            .collect();
        let (mut graph, mut last_seq) = match base {
            Some(b) => b,
            None => {
                if report.corrupt_snapshots > 0 {
                    report.problems.push(
                        "no usable snapshot: starting from the start scene and replaying the logs"
                            .into(),
                    );
                }
                (start_scene().map_err(PersistError::Scene)?, 0)
            }
        };
        for path in &logs {
            let bytes = std::fs::read(path).map_err(io_err(path))?;
            for (i, raw) in bytes.split(|b| *b == b'\n').enumerate() {
                let lineno = i + 1;
                if raw.iter().all(|b| b.is_ascii_whitespace()) {
                    continue;
                }
                let line: LogLine = match std::str::from_utf8(raw)
                    .map_err(|e| e.to_string())
                    .and_then(|s| serde_json::from_str(s).map_err(|e| e.to_string()))
                {
                    Ok(l) => l,
                    Err(e) => {
                        report.bad_lines += 1;
                        report.problems.push(format!(
                            "corrupt change line {}:{lineno}: {e} (skipped)",
                            path.display()
                        ));
                        continue;
                    }
                };
                if line.seq <= last_seq {
                    report.already_included += 1;
                    continue;
                }
                last_seq = line.seq;
                let applied = match (&line.event, &line.restore) {
                    (Some(ev), None) => graph.apply(ev),
                    (None, Some(snap)) => SceneGraph::restore(snap).map(|g| graph = g),
                    _ => Err(DrError::BadEvent(
                        "a line holds exactly one of `event` and `restore`".into(),
                    )),
                };
                match applied {
                    Ok(()) => report.replayed += 1,
                    Err(e) => {
                        report.failed_events += 1;
                        report.problems.push(format!(
                            "change {}:{lineno} (seq {}) no longer applies: {e} (skipped)",
                            path.display(),
                            line.seq
                        ));
                    }
                }
            }
        }
        report.last_seq = last_seq;
        let log_path = dir.join(LOG_FILE);
        let log = OpenOptions::new()
            .create(true)
            .append(true)
            .open(&log_path)
            .map_err(io_err(&log_path))?;
        let mut store = Store {
            dir: dir.to_path_buf(),
            log,
            options: StoreOptions {
                compact_every: options.compact_every.max(1),
                ..options
            },
            since_compaction: 0,
        };
        store.compact(&graph, last_seq)?;
        Ok((store, graph, report))
    }

    /// The state folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Appends change lines (one `write` call; `fdatasync` with [`StoreOptions::fsync`]).
    pub fn append(&mut self, lines: &[LogLine]) -> Result<(), PersistError> {
        if lines.is_empty() {
            return Ok(());
        }
        let mut text = String::new();
        for l in lines {
            text.push_str(&serde_json::to_string(l)?);
            text.push('\n');
        }
        let path = self.dir.join(LOG_FILE);
        self.log.write_all(text.as_bytes()).map_err(io_err(&path))?;
        if self.options.fsync {
            self.log.sync_data().map_err(io_err(&path))?;
        }
        self.since_compaction += lines.len();
        Ok(())
    }

    /// Whether [`StoreOptions::compact_every`] changes were appended since the last compaction.
    pub fn compaction_due(&self) -> bool {
        self.since_compaction >= self.options.compact_every
    }

    /// Changes appended since the last compaction.
    pub fn since_compaction(&self) -> usize {
        self.since_compaction
    }

    /// Writes `graph` (which includes every change up to `last_seq`) as the new snapshot and
    /// starts an empty log (see the module docs for the order of the steps).
    pub fn compact(&mut self, graph: &SceneGraph, last_seq: u64) -> Result<(), PersistError> {
        let state = StateFile {
            format: STATE_FORMAT.into(),
            version: SNAPSHOT_VERSION,
            last_seq,
            snapshot: graph.snapshot(),
        };
        let text = serde_json::to_string_pretty(&state)?;
        let tmp = self.dir.join(format!("{SNAPSHOT_FILE}.tmp"));
        {
            let mut f = File::create(&tmp).map_err(io_err(&tmp))?;
            f.write_all(text.as_bytes()).map_err(io_err(&tmp))?;
            f.sync_all().map_err(io_err(&tmp))?;
        }
        let snap = self.dir.join(SNAPSHOT_FILE);
        let log = self.dir.join(LOG_FILE);
        if snap.exists() {
            let prev = self.dir.join(PREV_SNAPSHOT_FILE);
            std::fs::rename(&snap, &prev).map_err(io_err(&snap))?;
        }
        if log.exists() {
            let prev = self.dir.join(PREV_LOG_FILE);
            std::fs::rename(&log, &prev).map_err(io_err(&log))?;
        }
        std::fs::rename(&tmp, &snap).map_err(io_err(&tmp))?;
        self.log = OpenOptions::new()
            .create(true)
            .append(true)
            .open(&log)
            .map_err(io_err(&log))?;
        if let Ok(d) = File::open(&self.dir) {
            // Make the renames durable; a folder that cannot be opened for sync is not an error.
            let _ = d.sync_all();
        }
        self.since_compaction = 0;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::At;
    use crate::types::{AttrValue, NodeSpec, NodeType, Stamp, StructuralChange, Transform};

    /// A fresh folder (or file path) in the temp dir, removed when the test ends.
    struct Scratch(PathBuf);

    impl std::ops::Deref for Scratch {
        type Target = Path;
        fn deref(&self) -> &Path {
            &self.0
        }
    }

    impl AsRef<Path> for Scratch {
        fn as_ref(&self) -> &Path {
            &self.0
        }
    }

    impl Drop for Scratch {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
            let _ = std::fs::remove_file(&self.0);
        }
    }

    #[expect(
        clippy::disallowed_methods,
        reason = "the wall's nanoseconds only make a scratch folder's name unique, not a time"
    )]
    fn scratch(tag: &str) -> Scratch {
        let d = std::env::temp_dir().join(format!(
            "dr-persist-{tag}-{}-{}",
            std::process::id(),
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map(|d| d.subsec_nanos())
                .unwrap_or(0)
        ));
        let _ = std::fs::remove_dir_all(&d);
        Scratch(d)
    }

    fn scene() -> crate::Result<SceneGraph> {
        let mut g = SceneGraph::new();
        g.propose(
            StructuralChange::add(NodeSpec::free(
                "ball",
                NodeType::Ball,
                "world",
                Transform::from_translation(1.0, 0.0, 0.0),
            )),
            Stamp(1),
        )
        .map_err(|r| DrError::Rejected(Box::new(r)))?;
        Ok(g)
    }

    /// A running service in miniature: apply changes with the graph's log on and append them.
    fn change(
        store: &mut Store,
        g: &mut SceneGraph,
        seq: &mut u64,
        f: impl FnOnce(&mut SceneGraph),
    ) {
        g.enable_log();
        f(g);
        let lines: Vec<LogLine> = g
            .take_log()
            .into_iter()
            .map(|e| {
                *seq += 1;
                LogLine {
                    seq: *seq,
                    event: Some(e),
                    restore: None,
                }
            })
            .collect();
        store.append(&lines).unwrap();
    }

    fn add_cup(g: &mut SceneGraph) {
        g.propose(
            StructuralChange::add(NodeSpec::free(
                "cup",
                NodeType::Object,
                "world",
                Transform::from_translation(0.5, 0.5, 0.8),
            )),
            Stamp(10),
        )
        .unwrap();
    }

    fn paint_ball(g: &mut SceneGraph, colour: &str) {
        g.set_attr("ball", "color", AttrValue::Text(colour.into()), Stamp(11))
            .unwrap();
    }

    fn colour(g: &SceneGraph) -> Option<AttrValue> {
        g.node("ball").unwrap().attrs.get("color").cloned()
    }

    #[test]
    fn a_fresh_folder_starts_from_the_scene_and_a_reopen_recovers_every_change() {
        let dir = scratch("fresh");
        let (mut store, mut g, report) = Store::open(&dir, StoreOptions::default(), scene).unwrap();
        assert!(report.is_fresh());
        assert!(dir.join(SNAPSHOT_FILE).is_file());
        let mut seq = report.last_seq;
        change(&mut store, &mut g, &mut seq, add_cup);
        change(&mut store, &mut g, &mut seq, |g| paint_ball(g, "red"));
        drop(store); // a SIGKILL: no compaction, only the appended lines
        let (_s, g2, report) = Store::open(&dir, StoreOptions::default(), || {
            panic!("the start scene must not be rebuilt")
        })
        .unwrap();
        assert_eq!(report.replayed, 2, "{report:?}");
        assert_eq!(report.last_seq, 2);
        assert!(report.problems.is_empty(), "{:?}", report.problems);
        assert!(g2.contains("cup"));
        assert_eq!(colour(&g2), Some(AttrValue::Text("red".into())));
        let t = g2.transform("world", "cup", At::Latest).unwrap();
        assert!((t.translation.vector.z - 0.8).abs() < 1e-12);
    }

    #[test]
    fn compaction_every_n_changes_rotates_the_files_and_loses_nothing() {
        let dir = scratch("compact");
        let opts = StoreOptions {
            compact_every: 2,
            fsync: true,
        };
        let (mut store, mut g, report) = Store::open(&dir, opts, scene).unwrap();
        let mut seq = report.last_seq;
        change(&mut store, &mut g, &mut seq, add_cup);
        assert!(!store.compaction_due());
        change(&mut store, &mut g, &mut seq, |g| paint_ball(g, "red"));
        assert!(store.compaction_due());
        store.compact(&g, seq).unwrap();
        assert_eq!(store.since_compaction(), 0);
        assert_eq!(std::fs::read_to_string(dir.join(LOG_FILE)).unwrap(), "");
        change(&mut store, &mut g, &mut seq, |g| paint_ball(g, "blue"));
        drop(store);
        let (_s, g2, report) = Store::open(&dir, opts, scene).unwrap();
        // Only the line after the compaction is replayed; the others are in the snapshot.
        assert_eq!(report.replayed, 1, "{report:?}");
        assert_eq!(report.last_seq, 3);
        assert!(g2.contains("cup"));
        assert_eq!(colour(&g2), Some(AttrValue::Text("blue".into())));
    }

    #[test]
    fn a_corrupt_snapshot_is_reported_and_the_previous_one_with_its_log_is_used() {
        let dir = scratch("corrupt-snap");
        let (mut store, mut g, report) = Store::open(&dir, StoreOptions::default(), scene).unwrap();
        let mut seq = report.last_seq;
        change(&mut store, &mut g, &mut seq, add_cup);
        store.compact(&g, seq).unwrap(); // snapshot.json has the cup; prev has not, prev log has it
        change(&mut store, &mut g, &mut seq, |g| paint_ball(g, "red"));
        drop(store);
        std::fs::write(
            dir.join(SNAPSHOT_FILE),
            "{\"format\": \"robocog-dr-state\", \"last_se",
        )
        .unwrap();

        let (_s, g2, report) = Store::open(&dir, StoreOptions::default(), scene).unwrap();
        assert_eq!(report.corrupt_snapshots, 1);
        assert_eq!(report.snapshot, Some(dir.join(PREV_SNAPSHOT_FILE)));
        let problem = &report.problems[0];
        assert!(problem.contains("snapshot.json"), "{problem}");
        assert!(problem.contains("EOF while parsing"), "{problem}");
        assert!(dir.join("snapshot.json.corrupt").is_file());
        // Nothing lost: the cup comes from the previous log, the colour from the current one.
        assert!(g2.contains("cup"));
        assert_eq!(colour(&g2), Some(AttrValue::Text("red".into())));
        assert_eq!(report.replayed, 2, "{report:?}");
        // And the folder is healthy again.
        assert!(load_state(&dir.join(SNAPSHOT_FILE)).is_ok());
    }

    #[test]
    fn a_corrupt_log_line_is_reported_with_its_number_skipped_and_counted() {
        let dir = scratch("corrupt-line");
        let (mut store, mut g, report) = Store::open(&dir, StoreOptions::default(), scene).unwrap();
        let mut seq = report.last_seq;
        change(&mut store, &mut g, &mut seq, add_cup);
        drop(store);
        // A damaged line in the middle, then a good change, then a torn last write.
        let mut f = OpenOptions::new()
            .append(true)
            .open(dir.join(LOG_FILE))
            .unwrap();
        f.write_all(b"{\"seq\": 2, \"event\": {\"event\": \"attribute_s\x00\n")
            .unwrap();
        let good = LogLine {
            seq: 3,
            event: Some(ChangeEvent::AttributeSet {
                stamp_ns: 12,
                node: "ball".into(),
                key: "color".into(),
                value: AttrValue::Text("green".into()),
            }),
            restore: None,
        };
        f.write_all(format!("{}\n", serde_json::to_string(&good).unwrap()).as_bytes())
            .unwrap();
        f.write_all(b"{\"seq\": 4, \"ev").unwrap();
        drop(f);

        let (_s, g2, report) = Store::open(&dir, StoreOptions::default(), scene).unwrap();
        assert_eq!(report.bad_lines, 2, "{report:?}");
        assert_eq!(report.replayed, 2);
        assert!(
            report.problems[0].contains("changes.log:2:"),
            "{:?}",
            report.problems
        );
        assert!(
            report.problems[1].contains("changes.log:4:"),
            "{:?}",
            report.problems
        );
        assert!(g2.contains("cup"));
        assert_eq!(colour(&g2), Some(AttrValue::Text("green".into())));
        assert_eq!(report.last_seq, 3);
    }

    #[test]
    fn a_restore_line_replaces_the_graph_on_replay() {
        let dir = scratch("restore");
        let (mut store, mut g, report) = Store::open(&dir, StoreOptions::default(), scene).unwrap();
        let mut seq = report.last_seq;
        change(&mut store, &mut g, &mut seq, add_cup);
        let empty = SceneGraph::new().snapshot();
        store
            .append(&[LogLine {
                seq: seq + 1,
                event: None,
                restore: Some(empty),
            }])
            .unwrap();
        drop(store);
        let (_s, g2, report) = Store::open(&dir, StoreOptions::default(), scene).unwrap();
        assert_eq!(report.replayed, 2);
        assert_eq!(g2.len(), 1, "only world is left");
    }

    #[test]
    fn an_unwritable_folder_is_an_error_naming_it() {
        let file = scratch("not-a-dir");
        std::fs::write(&file, "x").unwrap();
        let err = Store::open(&file, StoreOptions::default(), scene).unwrap_err();
        assert!(err.to_string().contains("not-a-dir"), "{err}");
    }
}
