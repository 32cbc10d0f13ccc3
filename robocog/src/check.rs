//! Graph checks that need the binaries: each one must exist, and, asked with `--describe`, say
//! what it publishes and subscribes, so that every input of the graph has a publisher of the same
//! type, every called service a server, and no hardware port two owners.

use crate::manifest::{Manifest, Origin, Problem, Problems};
use interfaces::node::Interface;
use std::collections::HashMap;
use std::io::Read;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// What a successful check learnt.
#[derive(Debug, Default)]
pub struct Report {
    pub interfaces: HashMap<String, Interface>,
    /// Things worth saying that are not errors (a binary that cannot describe itself).
    pub warnings: Vec<String>,
}

/// Ask `binary` for its interface, with a time-out.
pub fn describe(binary: &Path, args: &[String], timeout: Duration) -> Result<Interface, String> {
    let mut child = Command::new(binary)
        .args(args)
        .arg("--describe")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| format!("cannot run {}: {e}", binary.display()))?;
    let started = Instant::now();
    let status = loop {
        match child.try_wait() {
            Ok(Some(status)) => break status,
            Ok(None) if started.elapsed() > timeout => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(format!(
                    "`{} --describe` did not answer within {timeout:?}",
                    binary.display()
                ));
            }
            Ok(None) => std::thread::sleep(Duration::from_millis(10)),
            Err(e) => return Err(e.to_string()),
        }
    };
    let mut out = String::new();
    if let Some(mut o) = child.stdout.take() {
        let _ = o.read_to_string(&mut out);
    }
    if !status.success() {
        let mut err = String::new();
        if let Some(mut e) = child.stderr.take() {
            let _ = e.read_to_string(&mut err);
        }
        return Err(format!("`--describe` failed ({status}): {}", err.trim()));
    }
    serde_json::from_str(&out).map_err(|e| format!("`--describe` printed no interface: {e}"))
}

/// Check binaries, topics, services and hardware of `manifest`.
pub fn check(manifest: &Manifest) -> Result<Report, Problems> {
    let mut problems = Vec::new();
    let mut report = Report::default();
    for c in &manifest.components {
        match c.resolve_binary() {
            None => problems.push(Problem {
                origin: c.origin.clone(),
                message: format!(
                    "unknown binary {:?} for component {:?}: not next to robocog, not on PATH{}",
                    c.binary,
                    c.name,
                    if c.binary.contains('/') {
                        ", not at that path"
                    } else {
                        ""
                    }
                ),
            }),
            Some(path) => match describe(&path, &c.args, Duration::from_secs(10)) {
                Ok(i) => {
                    report.interfaces.insert(c.name.clone(), i);
                }
                Err(e) => report.warnings.push(format!(
                    "{}: component {:?} cannot describe its topics, so they are not checked: {e}",
                    c.origin, c.name
                )),
            },
        }
    }
    // Topic ends: every subscription needs a publisher of the same type in the graph.
    let mut publishers: HashMap<&str, Vec<(&str, &str)>> = HashMap::new();
    let mut servers: HashMap<&str, Vec<(&str, &str)>> = HashMap::new();
    for (name, i) in &report.interfaces {
        for p in &i.publishes {
            publishers
                .entry(&p.name)
                .or_default()
                .push((name, &p.type_name));
        }
        for s in &i.serves {
            servers
                .entry(&s.name)
                .or_default()
                .push((name, &s.type_name));
        }
    }
    let origin_of = |name: &str| -> Origin {
        manifest
            .component(name)
            .map(|c| c.origin.clone())
            .unwrap_or(Origin {
                file: manifest.file.clone(),
                line: 0,
            })
    };
    let mut names: Vec<&String> = report.interfaces.keys().collect();
    names.sort();
    for name in names {
        let i = &report.interfaces[name];
        let external = manifest
            .component(name)
            .map(|c| c.external_inputs.as_slice())
            .unwrap_or(&[]);
        for s in &i.subscribes {
            match publishers.get(s.name.as_str()) {
                None if external.contains(&s.name) => {}
                None => problems.push(Problem {
                    origin: origin_of(name),
                    message: format!(
                        "component {name:?} subscribes to {:?} ({}), which no component of the graph publishes",
                        s.name, s.type_name
                    ),
                }),
                Some(pubs) => {
                    for (p, t) in pubs {
                        if *t != s.type_name {
                            problems.push(Problem {
                                origin: origin_of(name),
                                message: format!(
                                    "component {name:?} expects {} on {:?}, but {p:?} publishes {t}",
                                    s.type_name, s.name
                                ),
                            });
                        }
                    }
                }
            }
        }
        for s in &i.calls {
            // A service served outside the graph (a robot left out of a replay) is declared as
            // an external input like a topic.
            if !servers.contains_key(s.name.as_str()) && !external.contains(&s.name) {
                problems.push(Problem {
                    origin: origin_of(name),
                    message: format!(
                        "component {name:?} calls service {:?}, which no component of the graph serves",
                        s.name
                    ),
                });
            }
        }
    }
    // Hardware the binaries claim themselves (after their arguments), against the manifest's.
    let mut claims: HashMap<String, String> = HashMap::new();
    for c in &manifest.components {
        for (h, _) in &c.hardware {
            claims.insert(h.clone(), c.name.clone());
        }
    }
    for c in &manifest.components {
        if let Some(i) = report.interfaces.get(&c.name) {
            for h in &i.hardware {
                match claims.get(h) {
                    Some(owner) if owner != &c.name => problems.push(Problem {
                        origin: c.origin.clone(),
                        message: format!(
                            "hardware {h:?} is claimed by both {owner:?} and {:?}",
                            c.name
                        ),
                    }),
                    _ => {
                        claims.insert(h.clone(), c.name.clone());
                    }
                }
            }
        }
    }
    if problems.is_empty() {
        Ok(report)
    } else {
        Err(Problems(problems))
    }
}
