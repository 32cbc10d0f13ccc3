//! JSGF grammars: loading, checking and expanding the subset robocog's grammars use.
//!
//! The subset: the `#JSGF V1.0;` header, `grammar name;`, comments (`//`, `/* */`), rules
//! `[public] <name> = expansion;` where an expansion is words, rule references `<name>`,
//! sequences, alternatives `|`, groups `( )` and optional parts `[ ]`. Weights, tags, `*`, `+` and
//! imports are refused (PocketSphinx would accept some, but the catalog check could not expand
//! them). A file that breaks these rules is an error naming the file and line before it ever
//! reaches the decoder.
//!
//! [`Grammar::sentences`] lists every sentence the public rules accept, which is how the test
//! suite checks a grammar against the command catalog.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A parsed grammar.
#[derive(Debug, Clone)]
pub struct Grammar {
    /// The `grammar name;` of the file.
    pub name: String,
    /// The text as read (what the decoder compiles).
    pub text: String,
    /// Where it came from (`<inline>` when from a string).
    pub origin: PathBuf,
    rules: BTreeMap<String, Expansion>,
    public: Vec<String>,
}

#[derive(Debug, Clone, PartialEq)]
enum Expansion {
    Word(String),
    Ref(String),
    Seq(Vec<Expansion>),
    Alt(Vec<Expansion>),
    Opt(Box<Expansion>),
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum GrammarError {
    #[error("grammar {file}: cannot read it: {message}")]
    Io { file: PathBuf, message: String },
    #[error("grammar {file}, line {line}: {message}")]
    Syntax {
        file: PathBuf,
        line: usize,
        message: String,
    },
    #[error("grammar {file}: {message}")]
    Semantic { file: PathBuf, message: String },
}

#[derive(Debug, Clone, PartialEq)]
enum Tok {
    Word(String),
    Ref(String),
    Sym(char),
}

fn tokenize(text: &str, file: &Path) -> Result<Vec<(Tok, usize)>, GrammarError> {
    let err = |line, message: String| GrammarError::Syntax {
        file: file.to_path_buf(),
        line,
        message,
    };
    let mut toks = Vec::new();
    let chars: Vec<char> = text.chars().collect();
    let (mut i, mut line) = (0, 1);
    while i < chars.len() {
        let c = chars[i];
        if c == '\n' {
            line += 1;
            i += 1;
        } else if c.is_whitespace() {
            i += 1;
        } else if c == '/' && chars.get(i + 1) == Some(&'/') {
            while i < chars.len() && chars[i] != '\n' {
                i += 1;
            }
        } else if c == '/' && chars.get(i + 1) == Some(&'*') {
            let start = line;
            i += 2;
            loop {
                if i + 1 >= chars.len() {
                    return Err(err(start, "unterminated /* comment".into()));
                }
                if chars[i] == '\n' {
                    line += 1;
                }
                if chars[i] == '*' && chars[i + 1] == '/' {
                    i += 2;
                    break;
                }
                i += 1;
            }
        } else if c == '<' {
            let j = i
                + 1
                + chars[i + 1..]
                    .iter()
                    .position(|&c| c == '>' || c == '\n')
                    .unwrap_or(chars.len() - i - 1);
            if chars.get(j) != Some(&'>') {
                return Err(err(line, "unterminated rule name '<...'".into()));
            }
            let name: String = chars[i + 1..j].iter().collect();
            if name.is_empty()
                || !name
                    .chars()
                    .all(|c| c.is_alphanumeric() || c == '_' || c == '.')
            {
                return Err(err(line, format!("bad rule name <{name}>")));
            }
            toks.push((Tok::Ref(name), line));
            i = j + 1;
        } else if "=|;()[]".contains(c) {
            toks.push((Tok::Sym(c), line));
            i += 1;
        } else if c.is_alphanumeric() || c == '\'' || c == '#' || c == '.' || c == '-' || c == '_' {
            let start = i;
            while i < chars.len() && (chars[i].is_alphanumeric() || "'#.-_".contains(chars[i])) {
                i += 1;
            }
            toks.push((Tok::Word(chars[start..i].iter().collect()), line));
        } else {
            return Err(err(
                line,
                format!("unexpected character {c:?} (weights, tags, * and + are not supported)"),
            ));
        }
    }
    Ok(toks)
}

struct Parser<'a> {
    toks: &'a [(Tok, usize)],
    i: usize,
    file: &'a Path,
}

impl Parser<'_> {
    fn line(&self) -> usize {
        self.toks
            .get(self.i)
            .or(self.toks.last())
            .map(|t| t.1)
            .unwrap_or(1)
    }
    fn err(&self, message: impl Into<String>) -> GrammarError {
        GrammarError::Syntax {
            file: self.file.to_path_buf(),
            line: self.line(),
            message: message.into(),
        }
    }
    fn peek(&self) -> Option<&Tok> {
        self.toks.get(self.i).map(|t| &t.0)
    }
    fn expect_sym(&mut self, c: char) -> Result<(), GrammarError> {
        match self.peek() {
            Some(Tok::Sym(s)) if *s == c => {
                self.i += 1;
                Ok(())
            }
            other => Err(self.err(format!("expected '{c}', found {}", describe(other)))),
        }
    }
    fn alternatives(&mut self) -> Result<Expansion, GrammarError> {
        let mut alts = vec![self.sequence()?];
        while self.peek() == Some(&Tok::Sym('|')) {
            self.i += 1;
            alts.push(self.sequence()?);
        }
        Ok(if alts.len() == 1 {
            alts.remove(0)
        } else {
            Expansion::Alt(alts)
        })
    }
    fn sequence(&mut self) -> Result<Expansion, GrammarError> {
        let mut items = Vec::new();
        loop {
            match self.peek() {
                Some(Tok::Word(w)) => {
                    items.push(Expansion::Word(w.to_lowercase()));
                    self.i += 1;
                }
                Some(Tok::Ref(r)) => {
                    items.push(Expansion::Ref(r.clone()));
                    self.i += 1;
                }
                Some(Tok::Sym('(')) => {
                    self.i += 1;
                    let e = self.alternatives()?;
                    self.expect_sym(')')?;
                    items.push(e);
                }
                Some(Tok::Sym('[')) => {
                    self.i += 1;
                    let e = self.alternatives()?;
                    self.expect_sym(']')?;
                    items.push(Expansion::Opt(Box::new(e)));
                }
                _ => break,
            }
        }
        if items.is_empty() {
            return Err(self.err(format!(
                "empty alternative before {}",
                describe(self.peek())
            )));
        }
        Ok(if items.len() == 1 {
            items.remove(0)
        } else {
            Expansion::Seq(items)
        })
    }
}

fn describe(t: Option<&Tok>) -> String {
    match t {
        None => "the end of the file".into(),
        Some(Tok::Word(w)) => format!("word {w:?}"),
        Some(Tok::Ref(r)) => format!("<{r}>"),
        Some(Tok::Sym(c)) => format!("'{c}'"),
    }
}

/// Upper bound on the sentences [`Grammar::sentences`] lists.
pub const MAX_SENTENCES: usize = 100_000;

impl Grammar {
    /// Read and check a grammar file.
    pub fn load(path: &Path) -> Result<Grammar, GrammarError> {
        let text = std::fs::read_to_string(path).map_err(|e| GrammarError::Io {
            file: path.to_path_buf(),
            message: e.to_string(),
        })?;
        Grammar::parse(&text, path)
    }

    /// Check a grammar's text; `origin` names it in errors.
    pub fn parse(text: &str, origin: &Path) -> Result<Grammar, GrammarError> {
        let toks = tokenize(text, origin)?;
        let mut p = Parser {
            toks: &toks,
            i: 0,
            file: origin,
        };
        // Header: #JSGF V1.0 [encoding [locale]];
        match p.peek() {
            Some(Tok::Word(w)) if w == "#JSGF" => p.i += 1,
            other => {
                return Err(p.err(format!(
                    "a grammar starts with '#JSGF V1.0;', found {}",
                    describe(other)
                )));
            }
        }
        while let Some(Tok::Word(_)) = p.peek() {
            p.i += 1;
        }
        p.expect_sym(';')?;
        let name = match (p.peek().cloned(), toks.get(p.i + 1).map(|t| t.0.clone())) {
            (Some(Tok::Word(g)), Some(Tok::Word(n))) if g == "grammar" => {
                p.i += 2;
                n
            }
            _ => return Err(p.err("expected 'grammar <name>;' after the header")),
        };
        p.expect_sym(';')?;
        let mut rules = BTreeMap::new();
        let mut public = Vec::new();
        while p.peek().is_some() {
            let is_public = matches!(p.peek(), Some(Tok::Word(w)) if w == "public");
            if is_public {
                p.i += 1;
            }
            let rule = match p.peek() {
                Some(Tok::Ref(r)) => r.clone(),
                other => {
                    return Err(p.err(format!(
                        "expected a rule name <...>, found {}",
                        describe(other)
                    )));
                }
            };
            p.i += 1;
            p.expect_sym('=')?;
            let e = p.alternatives()?;
            p.expect_sym(';')?;
            if rules.insert(rule.clone(), e).is_some() {
                return Err(p.err(format!("rule <{rule}> defined twice")));
            }
            if is_public {
                public.push(rule);
            }
        }
        let g = Grammar {
            name,
            text: text.to_string(),
            origin: origin.to_path_buf(),
            rules,
            public,
        };
        if g.public.is_empty() {
            return Err(g.semantic("no public rule"));
        }
        for e in g.rules.values() {
            g.check_refs(e, 0)?;
        }
        Ok(g)
    }

    fn semantic(&self, message: impl Into<String>) -> GrammarError {
        GrammarError::Semantic {
            file: self.origin.clone(),
            message: message.into(),
        }
    }

    fn check_refs(&self, e: &Expansion, depth: usize) -> Result<(), GrammarError> {
        if depth > 32 {
            return Err(
                self.semantic("rules refer to each other in a loop (recursion is not supported)")
            );
        }
        match e {
            Expansion::Word(_) => Ok(()),
            Expansion::Ref(r) => match self.rules.get(r) {
                Some(inner) => self.check_refs(inner, depth + 1),
                None if r == "NULL" || r == "VOID" => Ok(()),
                None => Err(self.semantic(format!("rule <{r}> is used but not defined"))),
            },
            Expansion::Seq(v) | Expansion::Alt(v) => {
                v.iter().try_for_each(|x| self.check_refs(x, depth))
            }
            Expansion::Opt(x) => self.check_refs(x, depth),
        }
    }

    fn expand(&self, e: &Expansion) -> Result<Vec<Vec<String>>, GrammarError> {
        let too_many = || self.semantic(format!("more than {MAX_SENTENCES} sentences"));
        Ok(match e {
            Expansion::Word(w) => vec![vec![w.clone()]],
            Expansion::Ref(r) if r == "NULL" => vec![vec![]],
            Expansion::Ref(r) if r == "VOID" => vec![],
            Expansion::Ref(r) => match self.rules.get(r) {
                Some(inner) => self.expand(inner)?,
                None => return Err(self.semantic(format!("rule <{r}> is used but not defined"))),
            },
            Expansion::Alt(v) => {
                let mut out = Vec::new();
                for x in v {
                    out.extend(self.expand(x)?);
                    if out.len() > MAX_SENTENCES {
                        return Err(too_many());
                    }
                }
                out
            }
            Expansion::Opt(x) => {
                let mut out = vec![vec![]];
                out.extend(self.expand(x)?);
                out
            }
            Expansion::Seq(v) => {
                let mut acc: Vec<Vec<String>> = vec![vec![]];
                for x in v {
                    let parts = self.expand(x)?;
                    if acc.len() * parts.len() > MAX_SENTENCES {
                        return Err(too_many());
                    }
                    acc = acc
                        .iter()
                        .flat_map(|a| {
                            parts.iter().map(move |p| {
                                let mut s = a.clone();
                                s.extend(p.iter().cloned());
                                s
                            })
                        })
                        .collect();
                }
                acc
            }
        })
    }

    /// Every sentence the public rules accept (words joined by single spaces), sorted, unique.
    pub fn sentences(&self) -> Result<Vec<String>, GrammarError> {
        let mut all = std::collections::BTreeSet::new();
        for r in &self.public {
            for s in self.expand(&Expansion::Ref(r.clone()))? {
                all.insert(s.join(" "));
            }
        }
        Ok(all.into_iter().collect())
    }

    /// Every word the grammar uses.
    pub fn words(&self) -> Result<Vec<String>, GrammarError> {
        let mut w: Vec<String> = self
            .sentences()?
            .iter()
            .flat_map(|s| s.split(' ').map(str::to_string).collect::<Vec<_>>())
            .filter(|w| !w.is_empty())
            .collect();
        w.sort();
        w.dedup();
        Ok(w)
    }
}

/// The folder of the grammars shipped with this crate: `$ROBOCOG_GRAMMARS` if set; else the
/// first `components/speech_recognition/grammars` found walking up from the working folder, then
/// from the executable's folder (a checkout's binaries run from it, or from its `target/`); else
/// this crate's folder as seen at build time (which another checkout may have removed: loading
/// a grammar then fails naming the path).
pub fn grammar_dir() -> PathBuf {
    if let Some(dir) = std::env::var_os("ROBOCOG_GRAMMARS") {
        return PathBuf::from(dir);
    }
    let starts = [
        std::env::current_dir().ok(),
        std::env::current_exe()
            .ok()
            .and_then(|e| e.parent().map(Path::to_path_buf)),
    ];
    for start in starts.into_iter().flatten() {
        for dir in start.ancestors() {
            let p = dir.join("components/speech_recognition/grammars");
            if p.is_dir() {
                return p;
            }
        }
    }
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("grammars")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(s: &str) -> Result<Grammar, GrammarError> {
        Grammar::parse(s, Path::new("test.gram"))
    }

    #[test]
    fn expands_optional_groups_and_references() {
        let g = parse(
            "#JSGF V1.0;\n// c\ngrammar t;\n/* block\n comment */\npublic <a> = [robot] (go | run) <b>;\n<b> = home | to the ball;\n",
        )
        .unwrap();
        assert_eq!(g.name, "t");
        let s = g.sentences().unwrap();
        assert_eq!(s.len(), 8);
        assert!(s.contains(&"robot run to the ball".to_string()));
        assert!(s.contains(&"go home".to_string()));
        assert_eq!(
            g.words().unwrap(),
            vec!["ball", "go", "home", "robot", "run", "the", "to"]
        );
    }

    #[test]
    fn syntax_errors_name_the_file_and_line() {
        let e = parse("#JSGF V1.0;\ngrammar t;\npublic <a> = go | ;\n").unwrap_err();
        assert!(matches!(e, GrammarError::Syntax { line: 3, .. }), "{e}");
        assert!(e.to_string().contains("test.gram, line 3"), "{e}");
        let e = parse("#JSGF V1.0;\ngrammar t;\npublic <a> = (go | run;\n").unwrap_err();
        assert!(e.to_string().contains("expected ')'"), "{e}");
        let e = parse("#JSGF V1.0;\ngrammar t;\npublic <a> = go /2/ run;\n").unwrap_err();
        assert!(matches!(e, GrammarError::Syntax { line: 3, .. }), "{e}");
        let e = parse("grammar t;\npublic <a> = go;\n").unwrap_err();
        assert!(e.to_string().contains("#JSGF"), "{e}");
        let e = parse("#JSGF V1.0;\ngrammar t;\npublic <a> = go <b>;\n").unwrap_err();
        assert!(e.to_string().contains("<b> is used but not defined"), "{e}");
        let e = parse("#JSGF V1.0;\ngrammar t;\n<a> = go;\n").unwrap_err();
        assert!(e.to_string().contains("no public rule"), "{e}");
        let e = parse("#JSGF V1.0;\ngrammar t;\npublic <a> = go <a>;\n").unwrap_err();
        assert!(e.to_string().contains("loop"), "{e}");
        let e = Grammar::load(Path::new("/nonexistent/x.gram")).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/x.gram"), "{e}");
    }
}
