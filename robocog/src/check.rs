//! Graph checks that need the binaries: each one must exist, and, asked with `--describe`, say
//! what it publishes and subscribes, so that every input of the graph has a publisher of the same
//! type, every called service a server, and no hardware port two owners; and, asked with
//! `--preflight`, whether it could start as configured (its own check of its files, models and
//! devices, the one it runs at start).

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

/// What a finished tool run printed.
struct Ran {
    status: std::process::ExitStatus,
    stdout: String,
    stderr: String,
}

/// Run `binary args extra` with `env`, reading its output as it comes (a chatty start cannot
/// fill a pipe and hang), killed after `timeout`.
fn run_with_timeout(
    binary: &Path,
    args: &[String],
    env: &[(String, String)],
    extra: &str,
    timeout: Duration,
) -> Result<Ran, String> {
    let mut child = Command::new(binary)
        .args(args)
        .arg(extra)
        .envs(env.iter().map(|(k, v)| (k, v)))
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| format!("cannot run {}: {e}", binary.display()))?;
    let (mut out, mut err) = (child.stdout.take(), child.stderr.take());
    std::thread::scope(|scope| {
        let stdout = scope.spawn(move || {
            let mut s = String::new();
            if let Some(o) = out.as_mut() {
                let _ = o.read_to_string(&mut s);
            }
            s
        });
        let stderr = scope.spawn(move || {
            let mut s = String::new();
            if let Some(e) = err.as_mut() {
                let _ = e.read_to_string(&mut s);
            }
            s
        });
        #[expect(
            clippy::disallowed_methods,
            reason = "a time-out on a real child process, polled on the wall"
        )]
        let started = Instant::now();
        #[expect(
            clippy::disallowed_methods,
            reason = "a time-out on a real child process, polled on the wall"
        )]
        let status = loop {
            match child.try_wait() {
                Ok(Some(status)) => break Ok(status),
                Ok(None) if started.elapsed() > timeout => {
                    let _ = child.kill();
                    let _ = child.wait();
                    break Err(format!(
                        "`{} {extra}` did not answer within {timeout:?}",
                        binary.display()
                    ));
                }
                Ok(None) => std::thread::sleep(Duration::from_millis(10)),
                Err(e) => {
                    let _ = child.kill();
                    let _ = child.wait();
                    break Err(e.to_string());
                }
            }
        };
        let stdout = stdout.join().unwrap_or_default();
        let stderr = stderr.join().unwrap_or_default();
        status.map(|status| Ran {
            status,
            stdout,
            stderr,
        })
    })
}

/// Ask `binary` for its interface (with the component's `env`: a Python component finds its
/// module through it), with a time-out.
pub fn describe(
    binary: &Path,
    args: &[String],
    env: &[(String, String)],
    timeout: Duration,
) -> Result<Interface, String> {
    let ran = run_with_timeout(binary, args, env, "--describe", timeout)?;
    if !ran.status.success() {
        return Err(format!(
            "`--describe` failed ({}): {}",
            ran.status,
            ran.stderr.trim()
        ));
    }
    serde_json::from_str(&ran.stdout).map_err(|e| format!("`--describe` printed no interface: {e}"))
}

/// How long one component may take to check its configuration (a speech model loads).
const PREFLIGHT_TIMEOUT: Duration = Duration::from_secs(60);

/// What `--preflight` said.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Preflight {
    /// It could start.
    Ready,
    /// It cannot tell before the graph runs (what it needs, another component makes).
    NotYet(String),
    /// It could not start: the component's own reason.
    Cannot(String),
}

/// Ask `binary` whether it could start as configured (`--preflight`).
pub fn preflight(
    binary: &Path,
    args: &[String],
    env: &[(String, String)],
    timeout: Duration,
) -> Preflight {
    let ran = match run_with_timeout(binary, args, env, "--preflight", timeout) {
        Ok(r) => r,
        Err(e) => return Preflight::Cannot(e),
    };
    // The component's own words: from its "cannot ..." line on (the error comes last), without
    // the name it starts with.
    let lines: Vec<&str> = ran
        .stderr
        .lines()
        .filter(|l| !l.trim().is_empty())
        .collect();
    let from = lines
        .iter()
        .rposition(|l| l.contains(": cannot start: ") || l.contains(": cannot be checked"))
        .unwrap_or(lines.len().saturating_sub(3));
    let said = lines[from..].join("\n    ");
    let said = said
        .split_once(": cannot start: ")
        .or_else(|| said.split_once(": cannot be checked before the graph runs: "))
        .map_or(said.as_str(), |(_, rest)| rest)
        .trim_end()
        .to_string();
    match ran.status.code() {
        Some(0) => Preflight::Ready,
        Some(c) if c == i32::from(interfaces::node::EX_TEMPFAIL) => Preflight::NotYet(said),
        Some(c) => Preflight::Cannot(format!("(exit {c}) {said}")),
        None => Preflight::Cannot(format!("({}) {said}", ran.status)),
    }
}

/// Check binaries, topics, services and hardware of `manifest`; with `preflight`, also ask every
/// component whether it could start as configured (its files, models and devices), all at once.
///
/// Over several machines, `machine` is the one this runs on: only its components (and those
/// placed on no machine) are preflighted here, and its certificate must be in the graph's
/// folder; the others are checked on their machines.
pub fn check(
    manifest: &Manifest,
    preflight: bool,
    machine: Option<&str>,
) -> Result<Report, Problems> {
    let mut problems = Vec::new();
    let mut report = Report::default();
    if let Some(m) = machine
        && !manifest.machines.is_empty()
    {
        match crate::machines::machine(manifest, m) {
            Err(e) => problems.push(Problem {
                origin: Origin {
                    file: manifest.file.clone(),
                    line: 0,
                },
                message: format!("{e:#}"),
            }),
            Ok(me) => {
                if me.is_tls()
                    && let Some(folder) = &manifest.certs
                    && let Err(e) = crate::machines::machine_certs(folder, &me.name)
                {
                    problems.push(Problem {
                        origin: me.origin.clone(),
                        message: format!("{e:#}"),
                    });
                }
            }
        }
    }
    let here = |c: &crate::manifest::Component| match (&c.machine, machine) {
        (None, _) => true,
        (Some(placed), Some(m)) => placed == m,
        (Some(_), None) => false,
    };
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
            Some(path) => match describe(
                &path,
                &c.args,
                &c.env
                    .iter()
                    .map(|(k, v)| (k.clone(), v.clone()))
                    .collect::<Vec<_>>(),
                Duration::from_secs(10),
            ) {
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
    if preflight {
        let checks: Vec<_> = manifest
            .components
            .iter()
            .filter(|c| report.interfaces.contains_key(&c.name))
            .filter(|c| here(c))
            .filter_map(|c| Some((c, c.resolve_binary()?)))
            .collect();
        for c in manifest.components.iter().filter(|c| !here(c)) {
            let on = c.machine.as_deref().unwrap_or("?");
            report.warnings.push(format!(
                "{}: component {:?} runs on machine {on:?}: its files and devices are checked there (robocog check --machine {on})",
                c.origin, c.name
            ));
        }
        let env: Vec<Vec<(String, String)>> = checks
            .iter()
            .map(|(c, _)| {
                c.env
                    .iter()
                    .map(|(k, v)| (k.clone(), v.clone()))
                    .chain([("ROBOCOG_COMPONENT".to_string(), c.name.clone())])
                    .collect()
            })
            .collect();
        let results: Vec<Preflight> = std::thread::scope(|scope| {
            let handles: Vec<_> = checks
                .iter()
                .zip(&env)
                .map(|((c, binary), env)| {
                    scope.spawn(move || {
                        crate::check::preflight(binary, &c.args, env, PREFLIGHT_TIMEOUT)
                    })
                })
                .collect();
            handles
                .into_iter()
                .map(|h| {
                    h.join().unwrap_or_else(|_| {
                        Preflight::Cannot("the preflight check panicked".into())
                    })
                })
                .collect()
        });
        for ((c, _), result) in checks.iter().zip(results) {
            match result {
                Preflight::Ready => {}
                Preflight::NotYet(e) => report.warnings.push(format!(
                    "{}: component {:?} cannot be checked before the graph runs: {e}",
                    c.origin, c.name
                )),
                Preflight::Cannot(e) => problems.push(Problem {
                    origin: c.origin.clone(),
                    message: format!("component {:?} cannot start {e}", c.name),
                }),
            }
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
    // Hardware the binaries claim themselves (after their arguments), against the manifest's,
    // per machine (a serial port on the robot and one of the same name on the speech machine
    // are two ports).
    let mut claims: HashMap<(String, String), String> = HashMap::new();
    let machine_of = |c: &crate::manifest::Component| c.machine.clone().unwrap_or_default();
    for c in &manifest.components {
        for (h, _) in &c.hardware {
            claims.insert((machine_of(c), h.clone()), c.name.clone());
        }
    }
    for c in &manifest.components {
        if let Some(i) = report.interfaces.get(&c.name) {
            for h in &i.hardware {
                let key = (machine_of(c), h.clone());
                match claims.get(&key) {
                    Some(owner) if owner != &c.name => problems.push(Problem {
                        origin: c.origin.clone(),
                        message: format!(
                            "hardware {h:?} is claimed by both {owner:?} and {:?}",
                            c.name
                        ),
                    }),
                    _ => {
                        claims.insert(key, c.name.clone());
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
