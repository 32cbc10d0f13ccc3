//! The garbage (filler) model: the words that let the decoder say "none of the commands".
//!
//! A grammar decoder always answers with some sentence of its grammar, so without an
//! alternative "what a lovely day" comes out as "well done". Each utterance is therefore decoded
//! twice: with the game's grammar and with a loop of filler words ([`garbage_jsgf`]). Speech that
//! fits no command is explained much better, acoustically, by a few frequent English words than
//! by any command; the comparison of the two path scores gives the confidence
//! ([`crate::confidence`]), and a low one makes the utterance out of grammar (`Command::None`).
//!
//! (Putting the loop into the command grammar as an alternative, `<command> | <filler>+`, was
//! tried first: in this PocketSphinx the loop then wins the Viterbi search on clean commands too,
//! and the lattice's N-best list mixes partial and cross-branch paths, so no usable posterior
//! comes out of it.)
//!
//! The filler list is a file (`grammars/filler.words`, one word per line, `#` comments) shared by
//! all games. When it is loaded for a grammar, the grammar's own words and every word that has a
//! pronunciation in common with one of them (a homophone: "know" for "no", "high" for "hi") are
//! removed, so a clean command never has an equally good filler path.

use std::collections::{BTreeSet, HashMap};
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum GarbageError {
    #[error("filler list {file}: cannot read it: {message}")]
    Io { file: PathBuf, message: String },
    #[error("filler list {file}, line {line}: {word:?} is not in the pronunciation dictionary")]
    UnknownWord {
        file: PathBuf,
        line: usize,
        word: String,
    },
    #[error("pronunciation dictionary {file}: cannot read it: {message}")]
    Dict { file: PathBuf, message: String },
}

/// The JSGF grammar of the garbage search: one or more of `fillers`, each costing the grammar
/// probability `word_weight` (so longer garbage paths pay more, as a word insertion penalty).
pub fn garbage_jsgf(fillers: &[String], word_weight: f64) -> String {
    let mut out =
        String::from("#JSGF V1.0;\ngrammar garbage;\npublic <garbage> = <filler>+;\n<filler> = ");
    for (i, w) in fillers.iter().enumerate() {
        if i > 0 {
            out.push_str(if i % 8 == 0 { "\n    | " } else { " | " });
        }
        out.push_str(&format!("/{word_weight}/ {w}"));
    }
    out.push_str(";\n");
    out
}

/// The shipped filler list.
pub fn filler_file() -> PathBuf {
    crate::grammar::grammar_dir().join("filler.words")
}

/// The shipped extra pronunciations of grammar words.
pub fn pronunciations_file() -> PathBuf {
    crate::grammar::grammar_dir().join("pronunciations.dict")
}

/// Extra pronunciations (`word PH O N ES` per line, `#` comments) as `(word, phones)` for the
/// decoder: a word the dictionary has becomes its next alternative (`word(2)`, ...); one it
/// has with the same phones is skipped; a new word is added as it is.
pub fn load_pronunciations(
    path: &Path,
    dict: &Dictionary,
) -> Result<Vec<(String, String)>, GarbageError> {
    let text = std::fs::read_to_string(path).map_err(|e| GarbageError::Dict {
        file: path.to_path_buf(),
        message: e.to_string(),
    })?;
    let mut out: Vec<(String, String)> = Vec::new();
    let mut added: HashMap<String, usize> = HashMap::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        let mut it = line.split_whitespace();
        let Some(word) = it.next() else { continue };
        let word = word.to_lowercase();
        let phones: Vec<&str> = it.collect();
        if phones.is_empty() || word.contains('(') {
            return Err(GarbageError::Dict {
                file: path.to_path_buf(),
                message: format!(
                    "line {}: want `word PH O N ES` (no `(2)`: alternatives are numbered here), got {line:?}",
                    i + 1
                ),
            });
        }
        let phones = phones.join(" ").to_uppercase();
        let known = dict.pronunciations(&word);
        if known.contains(&phones) {
            continue;
        }
        let n = added.entry(word.clone()).or_insert(known.len());
        *n += 1;
        let name = if *n == 1 {
            word
        } else {
            format!("{word}({n})")
        };
        out.push((name, phones));
    }
    Ok(out)
}

/// A pronunciation dictionary: word (lowercase) to its pronunciations (phone strings).
#[derive(Debug, Default)]
pub struct Dictionary {
    prons: HashMap<String, Vec<String>>,
}

impl Dictionary {
    /// Read a CMU-style dictionary (`word PH O N ES`, alternatives as `word(2) ...`).
    pub fn load(path: &Path) -> Result<Self, GarbageError> {
        let text = std::fs::read_to_string(path).map_err(|e| GarbageError::Dict {
            file: path.to_path_buf(),
            message: e.to_string(),
        })?;
        let mut prons: HashMap<String, Vec<String>> = HashMap::new();
        for line in text.lines() {
            let mut it = line.split_whitespace();
            let Some(head) = it.next() else { continue };
            let word = head.split('(').next().unwrap_or(head).to_lowercase();
            // A trailing "# comment" is allowed by the format.
            let phones: Vec<&str> = it.take_while(|p| !p.starts_with('#')).collect();
            prons.entry(word).or_default().push(phones.join(" "));
        }
        Ok(Self { prons })
    }

    pub fn contains(&self, word: &str) -> bool {
        self.prons.contains_key(word)
    }

    /// The word's pronunciations (phone strings), none when it is not in the dictionary.
    pub fn pronunciations(&self, word: &str) -> &[String] {
        self.prons.get(word).map(Vec::as_slice).unwrap_or(&[])
    }
}

/// Read a filler list: every word, lowercase, in file order, each checked against `dict`.
pub fn load_fillers(path: &Path, dict: &Dictionary) -> Result<Vec<String>, GarbageError> {
    let text = std::fs::read_to_string(path).map_err(|e| GarbageError::Io {
        file: path.to_path_buf(),
        message: e.to_string(),
    })?;
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let word = line.split('#').next().unwrap_or("").trim().to_lowercase();
        if word.is_empty() {
            continue;
        }
        if !dict.contains(&word) {
            return Err(GarbageError::UnknownWord {
                file: path.to_path_buf(),
                line: i + 1,
                word,
            });
        }
        if !out.contains(&word) {
            out.push(word);
        }
    }
    Ok(out)
}

/// `fillers` without the grammar's `words` and without any word sharing a pronunciation with one
/// of them.
pub fn without_grammar_words(
    fillers: &[String],
    words: &[String],
    dict: &Dictionary,
) -> Vec<String> {
    let taken: BTreeSet<&str> = words
        .iter()
        .flat_map(|w| dict.pronunciations(w).iter().map(String::as_str))
        .collect();
    fillers
        .iter()
        .filter(|f| !words.contains(f))
        .filter(|f| {
            !dict
                .pronunciations(f)
                .iter()
                .any(|p| taken.contains(p.as_str()))
        })
        .cloned()
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dict() -> Dictionary {
        let mut d = Dictionary::default();
        for (w, p) in [
            ("no", "N OW"),
            ("know", "N OW"),
            ("hi", "HH AY"),
            ("high", "HH AY"),
            ("day", "D EY"),
            ("cup", "K AH P"),
        ] {
            d.prons.entry(w.into()).or_default().push(p.into());
        }
        d
    }

    #[test]
    fn grammar_words_and_their_homophones_are_removed() {
        let f: Vec<String> = ["know", "high", "day", "cup", "no"]
            .map(String::from)
            .to_vec();
        let kept = without_grammar_words(&f, &["no".into(), "hi".into()], &dict());
        assert_eq!(kept, vec!["day", "cup"]);
    }

    #[test]
    fn extra_pronunciations_become_numbered_alternatives_and_bad_lines_name_the_line() {
        let p = std::env::temp_dir().join(format!("prons-{}.dict", std::process::id()));
        std::fs::write(
            &p,
            "# comment\nno N AH OW # British\nno n oh\nno N OW\nrobocog R OW B OW K AA G\n",
        )
        .unwrap();
        let got = load_pronunciations(&p, &dict()).unwrap();
        assert_eq!(
            got,
            vec![
                ("no(2)".to_string(), "N AH OW".to_string()),
                ("no(3)".to_string(), "N OH".to_string()),
                ("robocog".to_string(), "R OW B OW K AA G".to_string()),
            ]
        );
        std::fs::write(&p, "day D EY\ncup(2) K UH P\n").unwrap();
        let e = load_pronunciations(&p, &dict()).unwrap_err().to_string();
        assert!(e.contains("line 2") && e.contains("prons-"), "{e}");
        std::fs::write(&p, "lonely\n").unwrap();
        assert!(load_pronunciations(&p, &dict()).is_err());
        std::fs::remove_file(&p).unwrap();
    }

    #[test]
    fn an_unknown_filler_word_names_the_file_and_line() {
        let p = std::env::temp_dir().join(format!("fillers-{}.words", std::process::id()));
        std::fs::write(&p, "# comment\nday\n\ncup # a cup\nzzyzxqw\n").unwrap();
        let e = load_fillers(&p, &dict()).unwrap_err();
        assert!(e.to_string().contains("line 5"), "{e}");
        std::fs::write(&p, "# comment\nday\n\nCup # a cup\nday\n").unwrap();
        assert_eq!(load_fillers(&p, &dict()).unwrap(), vec!["day", "cup"]);
    }
}
