//! What a component keeps in its state folder (`ROBOCOG_STATE_DIR`, given by the launcher: it
//! outlives the component's restarts, and a new launch starts with a fresh one).

use std::path::Path;

/// Writes `bytes` to `path` so that a reader (the component restarted after a SIGKILL) never
/// finds half a file: into a temporary file beside it, renamed over it. The folder is made if it
/// is not there yet.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)?;
    }
    let mut tmp = path.as_os_str().to_os_string();
    tmp.push(".tmp");
    std::fs::write(&tmp, bytes)?;
    std::fs::rename(&tmp, path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_is_written_whole_into_a_folder_made_for_it() {
        let dir = std::env::temp_dir().join(format!("state-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let path = dir.join("component").join("kept.json");
        write_atomically(&path, b"{\"a\": 1}").unwrap();
        write_atomically(&path, b"{\"a\": 2}").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"{\"a\": 2}");
        let left: Vec<_> = std::fs::read_dir(path.parent().unwrap()).unwrap().collect();
        assert_eq!(left.len(), 1, "no temporary file left");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
