//! Drawing a definition: Mermaid `stateDiagram-v2` and Graphviz DOT.
//!
//! Node ids are the state's name when it is unique in the machine, else its path with `/`
//! replaced by `_`. Edge labels are `event [guard]`; timers read `after 5s (label)`; a
//! transition without a target is drawn as a loop marked `(no exit)`.

use std::collections::HashMap;
use std::fmt::Write;

use super::{Definition, StateId, StateKind, Trigger};

/// Mermaid words that cannot be node ids.
const RESERVED: &[&str] = &["end", "state", "note", "direction", "class", "classDef"];

impl<C, E, A> Definition<C, E, A> {
    fn diagram_ids(&self) -> Vec<String> {
        let mut count: HashMap<&str, usize> = HashMap::new();
        for s in self.states.iter().skip(1) {
            *count.entry(s.name.as_str()).or_default() += 1;
        }
        self.states
            .iter()
            .map(|s| {
                let unique = count.get(s.name.as_str()).copied() == Some(1)
                    && !RESERVED.contains(&s.name.as_str());
                let raw = if unique { &s.name } else { &s.path };
                raw.chars()
                    .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
                    .collect()
            })
            .collect()
    }

    fn edge_label(&self, ti: usize) -> String {
        let t = &self.transitions[ti];
        let mut l = match &t.trigger {
            Trigger::Event(e) => e.clone(),
            Trigger::After { delay, label } => {
                format!("after {} ({label})", super::fmt_duration(*delay))
            }
            Trigger::Eventless => String::new(),
        };
        if let Some(g) = &t.guard {
            if !l.is_empty() {
                l.push(' ');
            }
            let _ = write!(l, "[{}]", g.name);
        }
        if t.target.is_none() {
            l.push_str(" (no exit)");
        }
        l.trim().to_string()
    }

    /// The innermost compound or parallel state containing both `a` and `b` (0 = the root).
    fn container(&self, a: StateId, b: StateId) -> StateId {
        let anc_a = self.proper_ancestors(a, None);
        for x in anc_a {
            if x == 0 || b == x || self.is_descendant(b, x) {
                return x;
            }
        }
        0
    }

    /// The machine as a Mermaid `stateDiagram-v2`.
    pub fn mermaid(&self) -> String {
        let ids = self.diagram_ids();
        // Transitions grouped by the state whose block draws them.
        let mut edges: HashMap<StateId, Vec<usize>> = HashMap::new();
        for (ti, t) in self.transitions.iter().enumerate() {
            let c = self.container(t.source, t.target.unwrap_or(t.source));
            edges.entry(c).or_default().push(ti);
        }
        let mut out = String::from("stateDiagram-v2\n");
        self.mermaid_block(0, 1, &ids, &edges, &mut out);
        out
    }

    fn mermaid_block(
        &self,
        s: StateId,
        depth: usize,
        ids: &[String],
        edges: &HashMap<StateId, Vec<usize>>,
        out: &mut String,
    ) {
        let pad = "    ".repeat(depth);
        let st = &self.states[s];
        if let Some(init) = st.initial {
            let _ = writeln!(out, "{pad}[*] --> {}", ids[init]);
        }
        let mut first = true;
        for &c in &st.children {
            let cs = &self.states[c];
            if st.kind == StateKind::Parallel && !matches!(cs.kind, StateKind::History { .. }) {
                if !first {
                    let _ = writeln!(out, "{pad}--");
                }
                first = false;
            }
            let id = &ids[c];
            match cs.kind {
                StateKind::Compound | StateKind::Parallel => {
                    if *id != cs.name {
                        let _ = writeln!(out, "{pad}state \"{}\" as {id}", cs.name);
                    }
                    let _ = writeln!(out, "{pad}state {id} {{");
                    self.mermaid_block(c, depth + 1, ids, edges, out);
                    let _ = writeln!(out, "{pad}}}");
                }
                StateKind::History { deep } => {
                    let _ = writeln!(
                        out,
                        "{pad}state \"{}\" as {id}",
                        if deep { "H*" } else { "H" }
                    );
                }
                StateKind::Atomic | StateKind::Final => {
                    let _ = writeln!(out, "{pad}state \"{}\" as {id}", cs.name);
                }
            }
            if cs.kind == StateKind::Final {
                let _ = writeln!(out, "{pad}{id} --> [*]");
            }
        }
        for &ti in edges.get(&s).map(Vec::as_slice).unwrap_or(&[]) {
            let t = &self.transitions[ti];
            let from = &ids[t.source];
            let to = &ids[t.target.unwrap_or(t.source)];
            let label = self.edge_label(ti);
            if label.is_empty() {
                let _ = writeln!(out, "{pad}{from} --> {to}");
            } else {
                let _ = writeln!(out, "{pad}{from} --> {to} : {label}");
            }
        }
    }

    /// The machine as a Graphviz DOT digraph (clusters for compound and parallel states, dashed
    /// for parallel).
    pub fn dot(&self) -> String {
        let ids = self.diagram_ids();
        let mut out = String::new();
        let _ = writeln!(
            out,
            "digraph \"{}\" {{\n    compound=true;\n    node [shape=box, style=rounded];",
            self.name
        );
        let _ = writeln!(out, "    __start [shape=point];");
        self.dot_block(0, 1, &ids, &mut out);
        if let Some(init) = self.states[0].initial {
            let _ = writeln!(out, "    __start -> {};", self.dot_node(init, &ids));
        }
        for (ti, t) in self.transitions.iter().enumerate() {
            let target = t.target.unwrap_or(t.source);
            let mut attrs = vec![format!(
                "label=\"{}\"",
                self.edge_label(ti).replace('"', "'")
            )];
            if self.is_cluster(t.source) {
                attrs.push(format!("ltail=cluster_{}", ids[t.source]));
            }
            if self.is_cluster(target) {
                attrs.push(format!("lhead=cluster_{}", ids[target]));
            }
            let _ = writeln!(
                out,
                "    {} -> {} [{}];",
                self.dot_node(t.source, &ids),
                self.dot_node(target, &ids),
                attrs.join(", ")
            );
        }
        out.push_str("}\n");
        out
    }

    fn is_cluster(&self, s: StateId) -> bool {
        matches!(
            self.states[s].kind,
            StateKind::Compound | StateKind::Parallel
        )
    }

    fn dot_node(&self, s: StateId, ids: &[String]) -> String {
        if self.is_cluster(s) {
            format!("{}__anchor", ids[s])
        } else {
            ids[s].clone()
        }
    }

    fn dot_block(&self, s: StateId, depth: usize, ids: &[String], out: &mut String) {
        let pad = "    ".repeat(depth);
        for &c in &self.states[s].children {
            let cs = &self.states[c];
            let id = &ids[c];
            match cs.kind {
                StateKind::Compound | StateKind::Parallel => {
                    let style = if cs.kind == StateKind::Parallel {
                        "dashed"
                    } else {
                        "rounded"
                    };
                    let _ = writeln!(
                        out,
                        "{pad}subgraph cluster_{id} {{\n{pad}    label=\"{}\"; style={style};\n{pad}    {id}__anchor [shape=point, style=invis];",
                        cs.name
                    );
                    self.dot_block(c, depth + 1, ids, out);
                    let _ = writeln!(out, "{pad}}}");
                }
                StateKind::History { deep } => {
                    let _ = writeln!(
                        out,
                        "{pad}{id} [label=\"{}\", shape=circle];",
                        if deep { "H*" } else { "H" }
                    );
                }
                StateKind::Final => {
                    let _ = writeln!(
                        out,
                        "{pad}{id} [label=\"{}\", shape=doublecircle];",
                        cs.name
                    );
                }
                StateKind::Atomic => {
                    let _ = writeln!(out, "{pad}{id} [label=\"{}\"];", cs.name);
                }
            }
        }
    }
}
