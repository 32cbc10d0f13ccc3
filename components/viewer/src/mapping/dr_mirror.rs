//! The mirror of the deep representation: a snapshot, then its changes, drawn as frames at
//! most every `DR_DRAW_EVERY_NS`.

use super::*;

impl Mapper {
    /// Whether the DR mirror needs a `dr/snapshot` (none yet, or changes it could not apply).
    pub fn wants_dr_snapshot(&self) -> bool {
        self.dr.wants_snapshot
    }

    pub(super) fn dr_snapshot(&mut self, m: &dr::SnapshotData, out: &mut Vec<Logged>) {
        let restored = SceneGraph::restore(&m.snapshot).map_err(|e| e.to_string());
        match restored {
            Ok(g) => {
                let nodes = g.len();
                self.dr.graph = Some(g);
                self.dr.last_seq = m.last_seq;
                self.dr.wants_snapshot = false;
                self.dr.dirty = true;
                out.push(Logged::new(
                    "log/dr",
                    text(format!(
                        "snapshot: {nodes} nodes, up to change #{}",
                        m.last_seq
                    )),
                ));
            }
            Err(e) => out.push(Logged::new(
                "log/dr",
                warn(format!("snapshot not usable: {e}")),
            )),
        }
    }

    pub(super) fn dr_change(&mut self, m: &dr::DrChange, out: &mut Vec<Logged>) {
        // Joint values follow the joint states at 100 Hz: not worth a text line each.
        if !matches!(m.event, dr::ChangeEvent::JointSet { .. }) {
            out.push(Logged::new(
                "log/dr",
                text(format!("#{} {} {}", m.seq, m.event.kind(), m.event.node())),
            ));
        }
        let Some(g) = &mut self.dr.graph else {
            self.dr.wants_snapshot = true;
            return;
        };
        if m.seq <= self.dr.last_seq {
            return; // already in the snapshot
        }
        if matches!(m.event, dr::ChangeEvent::Restored) || m.seq != self.dr.last_seq + 1 {
            self.dr.wants_snapshot = true;
            self.dr.last_seq = m.seq;
            return;
        }
        self.dr.last_seq = m.seq;
        let applied = g.apply(&m.event).map_err(|e| e.to_string());
        match applied {
            Ok(()) => self.dr.dirty = true,
            Err(e) => {
                self.dr.wants_snapshot = true;
                out.push(Logged::new(
                    "log/dr",
                    warn(format!(
                        "change #{} not applied to the viewer's copy: {e}",
                        m.seq
                    )),
                ));
            }
        }
    }

    /// The DR's nodes, if they changed and the last drawing is older than [`DR_DRAW_EVERY_NS`]:
    /// each node at `dr/nodes/<name>` (`world_T_node` as a Transform3D, a labelled point), the
    /// edges as `dr/edges` (parent to child, in the world). Call often (every sample is fine).
    pub fn dr_draw(&mut self, now_ns: i64) -> Vec<Logged> {
        let mut out = Vec::new();
        if !self.dr.dirty || now_ns - self.dr.last_draw_ns < DR_DRAW_EVERY_NS {
            return out;
        }
        let Some(g) = &self.dr.graph else {
            return out;
        };
        self.dr.dirty = false;
        self.dr.last_draw_ns = now_ns;
        let mut drawn: HashMap<String, [f32; 7]> = HashMap::new();
        let mut edges: Vec<Vec<[f32; 3]>> = Vec::new();
        let mut world: HashMap<String, [f32; 3]> = HashMap::new();
        for (_, n) in g.nodes() {
            let Ok(w) = g.transform("world", &n.name, At::Latest) else {
                continue;
            };
            let t = w.translation.vector;
            let q = w.rotation.coords;
            world.insert(n.name.clone(), [t.x as f32, t.y as f32, t.z as f32]);
            if n.name == "world" {
                continue;
            }
            let key = [t.x, t.y, t.z, q.x, q.y, q.z, q.w].map(|v| v as f32);
            let path = format!("dr/nodes/{}", path_part(&n.name));
            match self.dr.drawn.get(&n.name) {
                // Unchanged since the last drawing: rerun keeps the latest value.
                Some(k) if k == &key => {}
                Some(_) => out.push(Logged::new(path, tr(&w))),
                None => {
                    out.push(Logged::new(path.clone(), tr(&w)));
                    out.push(Logged::new(
                        path,
                        rerun::Points3D::new([[0.0f32, 0.0, 0.0]])
                            .with_radii([0.008])
                            .with_colors([rerun::Color::from_rgb(170, 120, 220)])
                            .with_labels([format!("{} ({})", n.name, n.node_type.name())]),
                    ));
                }
            }
            drawn.insert(n.name.clone(), key);
        }
        for (_, n) in g.nodes() {
            if let Some(p) = n.parent.and_then(|p| g.node_by_id(p))
                && let (Some(a), Some(b)) = (world.get(&p.name), world.get(&n.name))
            {
                edges.push(vec![*a, *b]);
            }
        }
        out.push(Logged::new(
            "dr/edges",
            rerun::LineStrips3D::new(edges)
                .with_radii([0.002])
                .with_colors([rerun::Color::from_rgb(170, 120, 220)]),
        ));
        for gone in self.dr.drawn.keys().filter(|d| !drawn.contains_key(*d)) {
            out.push(Logged::new(
                format!("dr/nodes/{}", path_part(gone)),
                rerun::Clear::flat(),
            ));
        }
        self.dr.drawn = drawn;
        out
    }
}
