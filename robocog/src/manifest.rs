//! Launch manifests: a graph of components, strictly parsed.
//!
//! ```toml
//! include = ["common.toml"]          # other manifests, relative to this file, merged first
//!
//! [graph]
//! name = "touch_the_ball"
//! namespace = "loki"                 # --namespace wins; default "default"
//! router = "tcp/127.0.0.1:7447"      # the launcher's router; --router wins; port 0 = any free port
//! certs = "certs"                    # with [machines]: the folder of the graph's certificates
//!                                    # (ca.pem, <machine>.pem, <machine>.key; `robocog certs`)
//! insecure_bus = false               # true: allow plain tcp/ between machines (no TLS, no ACL)
//!
//! [machines.robot]                   # a graph over several machines (none: one machine)
//! router = "tls/10.0.0.2:7447"       # where the other machines reach this machine's router
//! [machines.speech]
//! router = "tls/10.0.0.3:7447"
//!
//! [vars]                             # ${name} in binary, args, env and hardware; --set name=value
//! robot = "sim"
//!
//! [profiles.real]                    # --profile real: these vars replace the defaults
//! robot = "dynamixel"
//!
//! [[component]]
//! name = "joint_motor"               # unique in the graph; its name on the bus
//! binary = "joint_motor"             # next to `robocog`, on PATH, or a path relative to this file
//! # python = "my_tracker:Tracker"    # instead of binary: a Python component (MODULE[:CLASS]),
//!                                    # run by $ROBOCOG_PYTHON (default python3) with the
//!                                    # `robocog` package (libs/python) installed
//! args = ["--driver", "${robot}"]
//! env = { RUST_LOG = "info" }
//! depends_on = ["deep_representation"]  # started once these are up (their liveliness token seen)
//! restart = "on-failure"             # never | on-failure | always
//! max_restarts = 5                   # then it has failed for good
//! backoff_ms = 500                   # first restart delay, doubled each time, at most 30 s
//! required = true                    # failed for good => the whole graph stops, exit code 1
//! ready_timeout_s = 15               # how long to wait for its liveliness token
//! stop_timeout_s = 5                 # SIGTERM, then SIGKILL after this long
//! hardware = ["serial:/dev/ttyUSB0"] # ports it claims; two claims of one port are an error
//! completes_graph = false            # true: when it exits 0, the graph is done (the launcher exits 0)
//! external_inputs = ["audio/in"]     # inputs fed from outside the graph (a bridge, a test, a user):
//!                                    # topics it subscribes to, or services it calls
//! machine = "robot"                  # with [machines]: where it runs (default, or "": the
//!                                    # launcher's); variables work here and in the routers
//! enabled = "${simulate}"            # "true" (default) or "false" after substitution, or a
//!                                    # comparison ("${tracker} == rust", "A != B"): a profile
//!                                    # can switch a simulator off when real hardware is used;
//!                                    # two components may share a name if at most one is enabled
//! ```
//!
//! Unknown keys are errors. Every error names the file and line.

use serde::Deserialize;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Duration;

mod raw;
use raw::{line_of, load_tree, substitute};

/// Where something was written.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Origin {
    pub file: PathBuf,
    pub line: usize,
}

impl fmt::Display for Origin {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}", self.file.display(), self.line)
    }
}

/// A problem in a manifest, at a place.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Problem {
    pub origin: Origin,
    pub message: String,
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.origin, self.message)
    }
}

/// Every problem found, not just the first.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Problems(pub Vec<Problem>);

impl fmt::Display for Problems {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, p) in self.0.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            write!(f, "error: {p}")?;
        }
        Ok(())
    }
}

impl std::error::Error for Problems {}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum RestartPolicy {
    /// Never restarted.
    Never,
    /// Restarted when it exits with an error or is killed by a signal.
    #[default]
    OnFailure,
    /// Restarted whenever it exits.
    Always,
}

/// One machine of a graph over several: its router, which the other machines' routers join.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Machine {
    pub name: String,
    /// The endpoint the other machines reach this machine's router on (`tls/10.0.0.2:7447`).
    pub router: String,
    pub origin: Origin,
}

impl Machine {
    /// Whether its router is reached with TLS.
    pub fn is_tls(&self) -> bool {
        self.router.starts_with("tls/")
    }
}

/// One component of a resolved graph.
#[derive(Debug, Clone)]
pub struct Component {
    pub name: String,
    /// As written (after substitution); see [`Component::resolve_binary`].
    pub binary: String,
    pub args: Vec<String>,
    pub env: BTreeMap<String, String>,
    pub depends_on: Vec<String>,
    pub restart: RestartPolicy,
    pub max_restarts: u32,
    pub backoff: Duration,
    pub required: bool,
    pub ready_timeout: Duration,
    pub stop_timeout: Duration,
    pub hardware: Vec<(String, Origin)>,
    pub completes_graph: bool,
    /// Topics it subscribes to that are published from outside the graph, and services it
    /// calls that are served from outside it.
    pub external_inputs: Vec<String>,
    pub origin: Origin,
    /// The directory of the manifest that declared it (relative binary paths start there).
    pub dir: PathBuf,
    /// The machine it runs on; `None`: the launcher's.
    pub machine: Option<String>,
}

/// A resolved graph: includes merged, variables substituted, checked.
#[derive(Debug, Clone)]
pub struct Manifest {
    pub name: String,
    pub namespace: Option<String>,
    pub router: Option<String>,
    pub vars: BTreeMap<String, String>,
    pub components: Vec<Component>,
    pub file: PathBuf,
    /// The machines of a graph over several (empty: everything on the launcher's machine).
    pub machines: Vec<Machine>,
    /// The folder of the graph's certificates (absolute, or relative to the top manifest's
    /// folder as written), for TLS between machines.
    pub certs: Option<PathBuf>,
    /// Plain tcp/ allowed between machines.
    pub insecure_bus: bool,
}

/// Options that change a manifest from the command line (shared by `check` and `launch`).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct Overrides {
    /// Use this profile's variables (e.g. `real` instead of the simulated drivers).
    #[arg(long)]
    pub profile: Option<String>,
    /// Override a variable: --set robot=real (repeatable); applied last.
    #[arg(long = "set", value_parser = parse_set)]
    pub set: Vec<(String, String)>,
}

/// Parse `key=value`.
pub fn parse_set(s: &str) -> Result<(String, String), String> {
    let (k, v) = s
        .split_once('=')
        .ok_or_else(|| format!("expected key=value, got {s:?}"))?;
    if k.is_empty() {
        return Err(format!("empty key in {s:?}"));
    }
    Ok((k.to_string(), v.to_string()))
}

impl Manifest {
    /// Load and resolve `path`: includes, profile, `--set`, substitution, and the structural
    /// checks (duplicates, unknown dependencies, cycles, hardware claims). Binaries and topics are
    /// checked by [`crate::check`].
    pub fn load(path: &Path, overrides: &Overrides) -> Result<Manifest, Problems> {
        let mut problems = Vec::new();
        let mut loaded = Vec::new();
        load_tree(path, &mut Vec::new(), &mut loaded, &mut problems, None);
        if !problems.is_empty() {
            return Err(Problems(problems));
        }
        let top = path.to_path_buf();
        let at_top = |line| Origin {
            file: top.clone(),
            line,
        };

        // Graph settings: the top file wins over includes.
        let (mut name, mut namespace, mut router) = (None, None, None);
        let (mut certs, mut insecure_bus) = (None, false);
        let mut machines: BTreeMap<String, Machine> = BTreeMap::new();
        let mut vars = BTreeMap::new();
        let mut profiles: BTreeMap<String, BTreeMap<String, String>> = BTreeMap::new();
        for l in &loaded {
            name = l.raw.graph.name.clone().or(name);
            namespace = l.raw.graph.namespace.clone().or(namespace);
            router = l.raw.graph.router.clone().or(router);
            if let Some(c) = &l.raw.graph.certs {
                let dir = l.file.parent().unwrap_or(Path::new(".")).to_path_buf();
                certs = Some((dir, c.clone()));
            }
            insecure_bus = l.raw.graph.insecure_bus.unwrap_or(insecure_bus);
            for (m, raw) in &l.raw.machines {
                let origin = Origin {
                    file: l.file.clone(),
                    line: line_of(&l.src, raw.span().start),
                };
                machines.insert(
                    m.clone(),
                    Machine {
                        name: m.clone(),
                        router: raw.get_ref().router.clone(),
                        origin,
                    },
                );
            }
            vars.extend(l.raw.vars.clone());
            for (p, v) in &l.raw.profiles {
                profiles.entry(p.clone()).or_default().extend(v.clone());
            }
        }
        if let Some(p) = &overrides.profile {
            match profiles.get(p) {
                Some(v) => vars.extend(v.clone()),
                None => {
                    let known: Vec<&str> = profiles.keys().map(String::as_str).collect();
                    problems.push(Problem {
                        origin: at_top(0),
                        message: format!("unknown profile {p:?} (known: {})", known.join(", ")),
                    });
                }
            }
        }
        for (k, v) in &overrides.set {
            vars.insert(k.clone(), v.clone());
        }
        // Variables in the machines' endpoints and the certificates' folder.
        for m in machines.values_mut() {
            match substitute(&m.router, &vars) {
                Ok(r) => m.router = r,
                Err(message) => problems.push(Problem {
                    origin: m.origin.clone(),
                    message,
                }),
            }
        }
        let certs: Option<PathBuf> = match certs {
            None => None,
            Some((dir, c)) => match substitute(&c, &vars) {
                Ok(c) => Some(dir.join(c)),
                Err(message) => {
                    problems.push(Problem {
                        origin: at_top(0),
                        message,
                    });
                    None
                }
            },
        };

        let all_names: HashSet<&str> = loaded
            .iter()
            .flat_map(|l| l.raw.component.iter().map(|c| c.name.get_ref().as_str()))
            .collect();
        let mut components: Vec<Component> = Vec::new();
        let mut disabled: Vec<(String, Origin)> = Vec::new();
        let mut first_seen: HashMap<String, Origin> = HashMap::new();
        for l in &loaded {
            let origin_of = |span: std::ops::Range<usize>| Origin {
                file: l.file.clone(),
                line: line_of(&l.src, span.start),
            };
            for rc in &l.raw.component {
                let origin = origin_of(rc.name.span());
                let sub_errors = std::cell::RefCell::new(Vec::new());
                let sub = |s: &str| match substitute(s, &vars) {
                    Ok(v) => v,
                    Err(message) => {
                        sub_errors.borrow_mut().push(Problem {
                            origin: origin.clone(),
                            message,
                        });
                        s.to_string()
                    }
                };
                let cname = rc.name.get_ref().clone();
                if let Some(enabled) = &rc.enabled {
                    match substitute(enabled.get_ref(), &vars).map(|v| truth(&v)) {
                        Ok(Ok(true)) => {}
                        Ok(Ok(false)) => {
                            disabled.push((cname, origin.clone()));
                            continue;
                        }
                        Ok(Err(other)) => {
                            problems.push(Problem {
                                origin: origin_of(enabled.span()),
                                message: format!(
                                    "enabled must be \"true\", \"false\" or a comparison \"A == B\" / \"A != B\" after substitution, got {other:?}"
                                ),
                            });
                            continue;
                        }
                        Err(message) => {
                            let message = message.clone();
                            problems.push(Problem {
                                origin: origin_of(enabled.span()),
                                message,
                            });
                            continue;
                        }
                    }
                }
                if !interfaces::topic::is_valid_segment(&cname) {
                    problems.push(Problem {
                        origin: origin.clone(),
                        message: format!(
                            "component name {cname:?}: use letters, digits, '_', '-', '.'"
                        ),
                    });
                }
                if let Some(first) = first_seen.get(&cname) {
                    problems.push(Problem {
                        origin: origin.clone(),
                        message: format!("duplicate component name {cname:?} (first at {first})"),
                    });
                    continue;
                }
                first_seen.insert(cname.clone(), origin.clone());
                // A Python component runs as `<python> -m robocog run MODULE[:CLASS] ARGS...`.
                let (binary, mut args) = match (&rc.binary, &rc.python) {
                    (Some(b), None) => (sub(b.get_ref()), Vec::new()),
                    (None, Some(module)) => (
                        python_interpreter(),
                        vec![
                            "-m".to_string(),
                            "robocog".to_string(),
                            "run".to_string(),
                            sub(module.get_ref()),
                        ],
                    ),
                    (b, _) => {
                        problems.push(Problem {
                            origin: origin.clone(),
                            message: format!(
                                "component {cname:?}: give `binary` (a program) or `python` (a Python module, `MODULE[:CLASS]`){}",
                                if b.is_some() { ", not both" } else { "" }
                            ),
                        });
                        continue;
                    }
                };
                args.extend(rc.args.iter().map(|a| sub(a)));
                let env = rc.env.iter().map(|(k, v)| (k.clone(), sub(v))).collect();
                let hardware = rc
                    .hardware
                    .iter()
                    .map(|h| (sub(h.get_ref()), origin_of(h.span())))
                    .collect();
                problems.extend(sub_errors.take());
                let secs = |s: f64, what: &str, problems: &mut Vec<Problem>| {
                    if s.is_finite() && s > 0.0 {
                        Duration::from_secs_f64(s)
                    } else {
                        problems.push(Problem {
                            origin: origin.clone(),
                            message: format!("{what} must be a positive number of seconds"),
                        });
                        Duration::from_secs(1)
                    }
                };
                let machine = match &rc.machine {
                    None => None,
                    Some(m) => {
                        let m_name = sub(m.get_ref());
                        if m_name.is_empty() {
                            // "" (a variable left empty): the launcher's machine.
                            None
                        } else if machines.contains_key(&m_name) {
                            Some(m_name)
                        } else {
                            let known: Vec<&str> = machines.keys().map(String::as_str).collect();
                            problems.push(Problem {
                                origin: origin_of(m.span()),
                                message: if known.is_empty() {
                                    format!(
                                        "component {cname:?} is placed on machine {m_name:?}, but the graph declares no [machines]"
                                    )
                                } else {
                                    format!(
                                        "component {cname:?} is placed on unknown machine {m_name:?} (machines: {})",
                                        known.join(", ")
                                    )
                                },
                            });
                            None
                        }
                    }
                };
                problems.extend(sub_errors.take());
                let ready_timeout = secs(rc.ready_timeout_s, "ready_timeout_s", &mut problems);
                let stop_timeout = secs(rc.stop_timeout_s, "stop_timeout_s", &mut problems);
                components.push(Component {
                    name: cname,
                    binary,
                    args,
                    env,
                    depends_on: rc.depends_on.iter().map(|d| d.get_ref().clone()).collect(),
                    restart: rc.restart,
                    max_restarts: rc.max_restarts,
                    backoff: Duration::from_millis(rc.backoff_ms.max(1)),
                    required: rc.required,
                    ready_timeout,
                    stop_timeout,
                    hardware,
                    completes_graph: rc.completes_graph,
                    external_inputs: rc.external_inputs.clone(),
                    origin: origin.clone(),
                    dir: l.file.parent().unwrap_or(Path::new(".")).to_path_buf(),
                    machine,
                });
                // Unknown dependencies, reported at the dependency's own line.
                for d in &rc.depends_on {
                    if !all_names.contains(d.get_ref().as_str()) {
                        problems.push(Problem {
                            origin: origin_of(d.span()),
                            message: format!(
                                "component {:?} depends on {:?}, which is not in the graph",
                                rc.name.get_ref(),
                                d.get_ref()
                            ),
                        });
                    }
                }
            }
        }
        for c in &components {
            for d in &c.depends_on {
                // Two entries may share a name when a profile enables one of them (a simulated
                // and a real driver of one role): depending on the name is fine while one is on.
                let enabled = components.iter().any(|o| &o.name == d);
                if let Some((_, at)) = disabled.iter().find(|(n, _)| n == d && !enabled) {
                    problems.push(Problem {
                        origin: c.origin.clone(),
                        message: format!(
                            "component {:?} depends on {d:?}, which is disabled ({at})",
                            c.name
                        ),
                    });
                }
            }
        }
        if components.is_empty() && problems.is_empty() {
            problems.push(Problem {
                origin: at_top(0),
                message: "the graph has no [[component]]".into(),
            });
        }

        // Two components claiming one hardware port of one machine (a component placed on no
        // machine is on the launcher's, which is not known here: "" stands for it).
        let mut claims: HashMap<(String, String), (String, Origin)> = HashMap::new();
        for c in &components {
            let machine = c.machine.clone().unwrap_or_default();
            for (h, origin) in &c.hardware {
                let key = (machine.clone(), h.clone());
                if let Some((other, first)) = claims.get(&key) {
                    if other != &c.name {
                        let on = if machine.is_empty() {
                            String::new()
                        } else {
                            format!(" on machine {machine:?}")
                        };
                        problems.push(Problem {
                            origin: origin.clone(),
                            message: format!(
                                "hardware {h:?}{on} is claimed by both {other:?} ({first}) and {:?}",
                                c.name
                            ),
                        });
                    }
                } else {
                    claims.insert(key, (c.name.clone(), origin.clone()));
                }
            }
        }
        problems.extend(check_machines(&machines, certs.as_deref(), insecure_bus));

        let manifest = Manifest {
            name: name.unwrap_or_else(|| {
                path.file_stem()
                    .map_or("graph".into(), |s| s.to_string_lossy().into_owned())
            }),
            namespace,
            router,
            vars,
            components,
            file: top,
            machines: machines.into_values().collect(),
            certs,
            insecure_bus,
        };
        if let Err(cycle) = manifest.start_order() {
            problems.push(cycle);
        }
        if problems.is_empty() {
            Ok(manifest)
        } else {
            Err(Problems(problems))
        }
    }

    /// The components in an order where each comes after its dependencies, or the cycle that
    /// prevents one.
    pub fn start_order(&self) -> Result<Vec<&Component>, Problem> {
        let index: HashMap<&str, usize> = self
            .components
            .iter()
            .enumerate()
            .map(|(i, c)| (c.name.as_str(), i))
            .collect();
        // 0 = unvisited, 1 = on the stack, 2 = done.
        let mut state = vec![0u8; self.components.len()];
        let mut order = Vec::new();
        let mut stack: Vec<usize> = Vec::new();
        fn visit<'a>(
            i: usize,
            m: &'a Manifest,
            index: &HashMap<&str, usize>,
            state: &mut [u8],
            stack: &mut Vec<usize>,
            order: &mut Vec<&'a Component>,
        ) -> Result<(), Problem> {
            if state[i] == 2 {
                return Ok(());
            }
            if state[i] == 1 {
                let start = stack.iter().position(|&s| s == i).unwrap_or(0);
                let mut names: Vec<&str> = stack[start..]
                    .iter()
                    .map(|&s| m.components[s].name.as_str())
                    .collect();
                names.push(&m.components[i].name);
                return Err(Problem {
                    origin: m.components[i].origin.clone(),
                    message: format!("dependency cycle: {}", names.join(" -> ")),
                });
            }
            state[i] = 1;
            stack.push(i);
            for d in &m.components[i].depends_on {
                if let Some(&j) = index.get(d.as_str()) {
                    visit(j, m, index, state, stack, order)?;
                }
            }
            stack.pop();
            state[i] = 2;
            order.push(&m.components[i]);
            Ok(())
        }
        for i in 0..self.components.len() {
            visit(i, self, &index, &mut state, &mut stack, &mut order)?;
        }
        Ok(order)
    }

    pub fn component(&self, name: &str) -> Option<&Component> {
        self.components.iter().find(|c| c.name == name)
    }
}

/// The machines' own problems: a name that cannot be a key segment, a router endpoint that is
/// not tcp/ or tls/ with a port, a router that leaves the host in plain tcp/ (unless the graph
/// says `insecure_bus`), TLS without a certificate folder.
fn check_machines(
    machines: &BTreeMap<String, Machine>,
    certs: Option<&Path>,
    insecure_bus: bool,
) -> Vec<Problem> {
    let mut problems = Vec::new();
    for m in machines.values() {
        let mut say = |message: String| {
            problems.push(Problem {
                origin: m.origin.clone(),
                message,
            })
        };
        if !interfaces::topics::is_valid_machine(&m.name) {
            say(format!(
                "machine name {:?}: use lowercase letters, digits, '_', '-'",
                m.name
            ));
        }
        let Some((proto, addr)) = m.router.split_once('/') else {
            say(format!(
                "machine {:?}: router {:?} is not an endpoint like tls/10.0.0.2:7447",
                m.name, m.router
            ));
            continue;
        };
        if !matches!(proto, "tcp" | "tls") {
            say(format!(
                "machine {:?}: router {:?}: the routers join over tls/ (or tcp/ with insecure_bus), not {proto}/",
                m.name, m.router
            ));
            continue;
        }
        let port_ok = addr
            .rsplit_once(':')
            .and_then(|(_, p)| p.parse::<u16>().ok())
            .is_some_and(|p| p != 0);
        if !port_ok {
            say(format!(
                "machine {:?}: router {:?} needs a fixed port (the other machines dial it)",
                m.name, m.router
            ));
        }
        let loopback =
            addr.starts_with("127.") || addr.starts_with("[::1]") || addr.starts_with("localhost:");
        if proto == "tcp" && !loopback && !insecure_bus {
            say(format!(
                "machine {:?}: router {:?} would carry the bus off this host unencrypted and open to anyone; use tls/ with [graph] certs (robocog certs makes them), or set insecure_bus = true in [graph]",
                m.name, m.router
            ));
        }
        if proto == "tls" && certs.is_none() {
            say(format!(
                "machine {:?}: router {:?} is TLS, but [graph] names no certs folder",
                m.name, m.router
            ));
        }
    }
    problems
}

impl Component {
    /// Find the executable: a path (relative to the manifest's folder) when it holds a `/`,
    /// otherwise next to the running `robocog`, then on `PATH`.
    pub fn resolve_binary(&self) -> Option<PathBuf> {
        resolve_binary(&self.binary, &self.dir)
    }
}

/// Whether an `enabled` value, after substitution, is on: `true`, `false`, or a comparison of
/// two words (`python == rust`, `sim != dynamixel`); anything else comes back as the error.
fn truth(value: &str) -> Result<bool, String> {
    match value.trim() {
        "true" => return Ok(true),
        "false" => return Ok(false),
        _ => {}
    }
    for (op, equal) in [("==", true), ("!=", false)] {
        if let Some((a, b)) = value.split_once(op) {
            let (a, b) = (a.trim(), b.trim());
            if !a.is_empty() && !b.is_empty() && !b.contains(['=', '!']) {
                return Ok((a == b) == equal);
            }
        }
    }
    Err(value.to_string())
}

/// The Python interpreter that runs `python = "..."` components: `ROBOCOG_PYTHON` (a venv's,
/// with the `robocog` package installed), else `python3`.
pub fn python_interpreter() -> String {
    std::env::var("ROBOCOG_PYTHON")
        .ok()
        .filter(|p| !p.is_empty())
        .unwrap_or_else(|| "python3".to_string())
}

/// See [`Component::resolve_binary`].
pub fn resolve_binary(binary: &str, dir: &Path) -> Option<PathBuf> {
    let is_exec = |p: &Path| {
        use std::os::unix::fs::PermissionsExt;
        p.is_file()
            && p.metadata()
                .map(|m| m.permissions().mode() & 0o111 != 0)
                .unwrap_or(false)
    };
    if binary.contains('/') {
        let p = dir.join(binary);
        return is_exec(&p).then_some(p);
    }
    let mut candidates = Vec::new();
    if let Ok(exe) = std::env::current_exe()
        && let Some(d) = exe.parent()
    {
        candidates.push(d.join(binary));
        // Running from target/<profile>/deps (a test binary): the binaries are one level up.
        if d.ends_with("deps")
            && let Some(up) = d.parent()
        {
            candidates.push(up.join(binary));
        }
    }
    if let Some(path) = std::env::var_os("PATH") {
        candidates.extend(std::env::split_paths(&path).map(|d| d.join(binary)));
    }
    candidates.into_iter().find(|p| is_exec(p))
}

#[cfg(test)]
mod tests;
