//! PDDL export of the current state, and a small PDDL reader for problems (and domains' headers).
//!
//! The domain is `libs/world_model/pddl/robocog-domain.pddl` ([`DOMAIN`] embeds it). A problem
//! declares as objects every node that a true fact mentions, typed by node type (`ball`, `item`
//! for other objects, `robot`, `human`, `camera`, `goalpost`, `landmark`, `field`, `effector` for
//! hand links) and the declared body parts (`bodypart`); `:init` lists the true facts of
//! [`crate::predicates::evaluate`] plus `has-part` and `has-camera`.
//!
//! Names: PDDL is case-insensitive and allows `[a-z][a-z0-9_-]*`, so node names are lowercased
//! and other characters become `-` ([`pddl_name`]); names that don't start with a letter get an
//! `n-` prefix. Keep DR names in that alphabet if they must map back one to one.

use std::collections::{BTreeMap, BTreeSet};

use crate::error::{DrError, Result};
use crate::graph::{At, SceneGraph};
use crate::predicates::{PredicateConfig, evaluate};
use crate::types::NodeType;

/// The domain file's text.
pub const DOMAIN: &str = include_str!("../pddl/robocog-domain.pddl");
/// The domain's name.
pub const DOMAIN_NAME: &str = "robocog";

/// A ground atom: predicate name and arguments (PDDL names).
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Atom {
    /// Predicate (PDDL name, e.g. `in-field`).
    pub predicate: String,
    /// Arguments.
    pub args: Vec<String>,
}

impl Atom {
    /// An atom from string slices.
    pub fn new(predicate: &str, args: &[&str]) -> Self {
        Self {
            predicate: predicate.into(),
            args: args.iter().map(|a| a.to_string()).collect(),
        }
    }
    fn write(&self, out: &mut String) {
        out.push('(');
        out.push_str(&self.predicate);
        for a in &self.args {
            out.push(' ');
            out.push_str(a);
        }
        out.push(')');
    }
}

/// A PDDL problem: objects with types, initial atoms and goal atoms (a conjunction).
#[derive(Debug, Clone, PartialEq)]
pub struct PddlProblem {
    /// Problem name.
    pub name: String,
    /// Domain name.
    pub domain: String,
    /// Object name to type.
    pub objects: BTreeMap<String, String>,
    /// True atoms.
    pub init: BTreeSet<Atom>,
    /// Goal conjunction.
    pub goal: Vec<Atom>,
}

/// A DR name as a PDDL name (see the module docs).
pub fn pddl_name(s: &str) -> String {
    let mut out: String = s
        .chars()
        .map(|c| {
            let c = c.to_ascii_lowercase();
            if c.is_ascii_alphanumeric() || c == '_' || c == '-' {
                c
            } else {
                '-'
            }
        })
        .collect();
    if !out.starts_with(|c: char| c.is_ascii_alphabetic()) {
        out.insert_str(0, "n-");
    }
    out
}

fn pddl_type(g: &SceneGraph, name: &str) -> Option<&'static str> {
    if g.body_part(name).is_some() {
        return Some("bodypart");
    }
    let n = g.node(name).ok()?;
    Some(match n.node_type {
        NodeType::Camera => "camera",
        NodeType::Ball => "ball",
        NodeType::Object => "item",
        NodeType::Human => "human",
        NodeType::Robot => "robot",
        NodeType::Goalpost => "goalpost",
        NodeType::Landmark => "landmark",
        NodeType::Field => "field",
        NodeType::Link | NodeType::Frame => {
            if n.flag(crate::types::attr::EFFECTOR) == Some(true) {
                "effector"
            } else {
                return None;
            }
        }
        NodeType::World => return None,
    })
}

/// Builds the problem for the graph's state at `at`, with a goal conjunction (DR names; they are
/// converted with [`pddl_name`]). Landmarks, the field and cameras are declared even when no fact
/// mentions them.
pub fn export_problem(
    g: &SceneGraph,
    cfg: &PredicateConfig,
    at: At,
    problem_name: &str,
    goal: &[Atom],
) -> Result<PddlProblem> {
    let facts = evaluate(g, cfg, at)?;
    let mut objects = BTreeMap::new();
    let mut init = BTreeSet::new();
    let declare = |objects: &mut BTreeMap<String, String>, name: &str| {
        if let Some(t) = pddl_type(g, name) {
            objects.insert(pddl_name(name), t.to_string());
        }
    };
    for (_, n) in g.nodes() {
        if matches!(
            n.node_type,
            NodeType::Camera
                | NodeType::Ball
                | NodeType::Object
                | NodeType::Human
                | NodeType::Robot
                | NodeType::Goalpost
                | NodeType::Landmark
                | NodeType::Field
        ) {
            declare(&mut objects, &n.name);
        }
    }
    for f in &facts {
        for a in &f.args {
            declare(&mut objects, a);
        }
        init.insert(Atom {
            predicate: f.kind.pddl_name().into(),
            args: f.args.iter().map(|a| pddl_name(a)).collect(),
        });
    }
    for b in g.body_parts() {
        declare(&mut objects, &b.name);
        init.insert(Atom::new(
            "has-part",
            &[&pddl_name(&b.robot), &pddl_name(&b.name)],
        ));
    }
    // has-camera: a camera belongs to the robot agent above it.
    for (id, n) in g.nodes().filter(|(_, n)| n.node_type == NodeType::Camera) {
        let mut cur = g.node_by_id(id).and_then(|n| n.parent);
        while let Some(p) = cur.and_then(|p| g.node_by_id(p)) {
            if p.node_type == NodeType::Robot {
                init.insert(Atom::new(
                    "has-camera",
                    &[&pddl_name(&p.name), &pddl_name(&n.name)],
                ));
                break;
            }
            cur = p.parent;
        }
    }
    let goal = goal
        .iter()
        .map(|a| Atom {
            predicate: a.predicate.clone(),
            args: a.args.iter().map(|s| pddl_name(s)).collect(),
        })
        .collect();
    Ok(PddlProblem {
        name: pddl_name(problem_name),
        domain: DOMAIN_NAME.into(),
        objects,
        init,
        goal,
    })
}

impl PddlProblem {
    /// The problem file text.
    pub fn to_pddl(&self) -> String {
        let mut s = format!(
            "(define (problem {})\n  (:domain {})\n  (:objects",
            self.name, self.domain
        );
        let mut by_type: BTreeMap<&str, Vec<&str>> = BTreeMap::new();
        for (o, t) in &self.objects {
            by_type.entry(t).or_default().push(o);
        }
        for (t, objs) in by_type {
            s.push_str("\n    ");
            s.push_str(&objs.join(" "));
            s.push_str(" - ");
            s.push_str(t);
        }
        s.push_str(")\n  (:init");
        for a in &self.init {
            s.push_str("\n    ");
            a.write(&mut s);
        }
        s.push_str(")\n  (:goal (and");
        for a in &self.goal {
            s.push(' ');
            a.write(&mut s);
        }
        s.push_str(")))\n");
        s
    }

    /// Parses a problem file: `define`, `problem`, `:domain`, `:objects` (typed lists),
    /// `:init` (ground atoms) and `:goal` (an atom or an `and` of atoms). Other sections are errors.
    pub fn parse(text: &str) -> Result<Self> {
        let sx = parse_sexpr(text)?;
        let top = sx.list("top level")?;
        if top.first().and_then(Sexpr::atom) != Some("define") {
            return Err(perr("expected (define ...)"));
        }
        let head = top
            .get(1)
            .ok_or_else(|| perr("missing (problem NAME)"))?
            .list("problem header")?;
        let name = match head {
            [Sexpr::Atom(p), Sexpr::Atom(n)] if p == "problem" => n.clone(),
            _ => return Err(perr("expected (problem NAME)")),
        };
        let mut prob = PddlProblem {
            name,
            domain: String::new(),
            objects: BTreeMap::new(),
            init: BTreeSet::new(),
            goal: Vec::new(),
        };
        for sec in &top[2..] {
            let items = sec.list("section")?;
            let key = items
                .first()
                .and_then(Sexpr::atom)
                .ok_or_else(|| perr("empty section"))?;
            let rest = &items[1..];
            match key {
                ":domain" => {
                    prob.domain = rest
                        .first()
                        .and_then(Sexpr::atom)
                        .ok_or_else(|| perr(":domain needs a name"))?
                        .to_string();
                }
                ":objects" => {
                    let mut pending: Vec<String> = Vec::new();
                    let mut it = rest.iter();
                    while let Some(x) = it.next() {
                        let a = x.atom().ok_or_else(|| perr(":objects holds names only"))?;
                        if a == "-" {
                            let t = it
                                .next()
                                .and_then(Sexpr::atom)
                                .ok_or_else(|| perr(":objects: `-` without a type"))?;
                            for o in pending.drain(..) {
                                prob.objects.insert(o, t.to_string());
                            }
                        } else {
                            pending.push(a.to_string());
                        }
                    }
                    for o in pending {
                        prob.objects.insert(o, "object".into());
                    }
                }
                ":init" => {
                    for a in rest {
                        prob.init.insert(a.ground_atom()?);
                    }
                }
                ":goal" => {
                    let g = rest.first().ok_or_else(|| perr(":goal is empty"))?;
                    let l = g.list("goal")?;
                    if l.first().and_then(Sexpr::atom) == Some("and") {
                        for a in &l[1..] {
                            prob.goal.push(a.ground_atom()?);
                        }
                    } else {
                        prob.goal.push(g.ground_atom()?);
                    }
                }
                other => return Err(perr(&format!("unsupported section `{other}`"))),
            }
        }
        Ok(prob)
    }
}

fn perr(s: &str) -> DrError {
    DrError::PddlParse(s.to_string())
}

/// An s-expression.
#[derive(Debug, Clone, PartialEq)]
pub enum Sexpr {
    /// A symbol (lowercased).
    Atom(String),
    /// A parenthesised list.
    List(Vec<Sexpr>),
}

impl Sexpr {
    /// The symbol, if this is one.
    pub fn atom(&self) -> Option<&str> {
        match self {
            Sexpr::Atom(a) => Some(a),
            Sexpr::List(_) => None,
        }
    }
    /// The items, or an error naming `what`.
    pub fn list(&self, what: &str) -> Result<&[Sexpr]> {
        match self {
            Sexpr::List(l) => Ok(l),
            Sexpr::Atom(a) => Err(perr(&format!("{what}: expected a list, found `{a}`"))),
        }
    }
    fn ground_atom(&self) -> Result<Atom> {
        let l = self.list("atom")?;
        let mut names = l
            .iter()
            .map(|x| x.atom().ok_or_else(|| perr("atoms hold names only")));
        let predicate = names.next().ok_or_else(|| perr("empty atom"))??.to_string();
        let args = names
            .map(|r| r.map(str::to_string))
            .collect::<Result<Vec<_>>>()?;
        Ok(Atom { predicate, args })
    }
}

/// Reads one s-expression (`;` comments allowed); trailing text is an error.
pub fn parse_sexpr(text: &str) -> Result<Sexpr> {
    let mut stack: Vec<Vec<Sexpr>> = Vec::new();
    let mut done: Option<Sexpr> = None;
    let mut chars = text.char_indices().peekable();
    let mut line = 1;
    while let Some((i, c)) = chars.next() {
        if done.is_some() && !c.is_whitespace() && c != ';' {
            return Err(perr(&format!(
                "line {line}: text after the end of the expression"
            )));
        }
        match c {
            '\n' => line += 1,
            ';' => {
                while let Some((_, c)) = chars.next_if(|(_, c)| *c != '\n') {
                    let _ = c;
                }
            }
            '(' => stack.push(Vec::new()),
            ')' => {
                let l = stack
                    .pop()
                    .ok_or_else(|| perr(&format!("line {line}: unbalanced `)`")))?;
                match stack.last_mut() {
                    Some(parent) => parent.push(Sexpr::List(l)),
                    None => done = Some(Sexpr::List(l)),
                }
            }
            c if c.is_whitespace() => {}
            _ => {
                let mut end = i + c.len_utf8();
                while let Some((j, d)) =
                    chars.next_if(|(_, d)| !d.is_whitespace() && !"();".contains(*d))
                {
                    end = j + d.len_utf8();
                }
                let a = Sexpr::Atom(text[i..end].to_ascii_lowercase());
                match stack.last_mut() {
                    Some(l) => l.push(a),
                    None => return Err(perr(&format!("line {line}: symbol outside a list"))),
                }
            }
        }
    }
    if !stack.is_empty() {
        return Err(perr("unbalanced `(`: the text ends inside a list"));
    }
    done.ok_or_else(|| perr("empty text"))
}

/// Predicate names and arities, and type names, declared by a domain text.
pub fn domain_signature(text: &str) -> Result<(BTreeMap<String, usize>, BTreeSet<String>)> {
    let top = parse_sexpr(text)?;
    let mut preds = BTreeMap::new();
    let mut types = BTreeSet::from(["object".to_string()]);
    for sec in top.list("domain")?.iter().skip(2) {
        let Ok(items) = sec.list("section") else {
            continue;
        };
        match items.first().and_then(Sexpr::atom) {
            Some(":predicates") => {
                for p in &items[1..] {
                    let l = p.list("predicate")?;
                    let name = l
                        .first()
                        .and_then(Sexpr::atom)
                        .ok_or_else(|| perr("predicate name"))?;
                    let arity = l
                        .iter()
                        .filter_map(Sexpr::atom)
                        .filter(|a| a.starts_with('?'))
                        .count();
                    preds.insert(name.to_string(), arity);
                }
            }
            Some(":types") => {
                for a in items[1..]
                    .iter()
                    .filter_map(Sexpr::atom)
                    .filter(|a| *a != "-")
                {
                    types.insert(a.to_string());
                }
            }
            _ => {}
        }
    }
    Ok((preds, types))
}
