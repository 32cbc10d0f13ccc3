//! Self-collision checks on the URDF collision geometry.
//!
//! # Geometry
//! Each link's collision elements (link frame, m) become primitives:
//! - a **sphere** stays a sphere (a capsule with a zero-length segment);
//! - a **cylinder** of radius `r` and length `L` along its z axis becomes the capsule of radius `r`
//!   around the segment of length `L` (it contains the cylinder; the ends bulge by `r`);
//! - a URDF **capsule** is exact;
//! - a **box** stays an oriented box. Box-box pairs are tested with the smaller box replaced by
//!   its bounding capsule (segment along its longest side, radius the half-diagonal of the other
//!   two sides), a conservative approximation;
//! - meshes are ignored, and so are the 5 mm marker spheres of virtual frames (tip and optical
//!   frames, `base_footprint`): spheres of radius <= [`MARKER_RADIUS_M`].
//!
//! Two primitives intersect when their distance is below 0 (capsule-capsule: exact segment
//! distance; capsule-box: segment-to-box distance, minimised along the segment by golden-section
//! search, which is exact to ~1e-9 m since the distance is convex along the segment).
//!
//! # Which pairs are checked
//! Like an SRDF's disabled-collision list, a pair of links is never checked when the links are
//! (a) joined by a joint (adjacent), (b) rigidly attached through fixed joints only, or
//! (c) within 1 mm of each other in the reference posture (every joint at 0, clamped into its
//! limits), since they are in contact by design (for example the upper arm against the torso:
//! the forearm, hand and fingers are still checked against the torso).

use nalgebra::{Isometry3, Point3, Vector3};
use robot_model::{RobotModel, Shape, TransformIso};

/// Spheres up to this radius (m) are frame markers, not bodies.
pub const MARKER_RADIUS_M: f64 = 0.005;

/// Distance (m) below which a pair touching in the reference posture is disabled.
const DEFAULT_CONTACT_M: f64 = 1e-3;

#[derive(Debug, Clone, Copy)]
enum Prim {
    /// Segment `a`-`b` (link frame) swept by a sphere of radius `r`.
    Capsule {
        a: Point3<f64>,
        b: Point3<f64>,
        r: f64,
    },
    /// Box placed by `pose` (link frame) with half sides `half`.
    Box {
        pose: Isometry3<f64>,
        half: Vector3<f64>,
    },
}

impl Prim {
    /// Centre and radius of a bounding sphere, link frame.
    fn bounding(&self) -> (Point3<f64>, f64) {
        match self {
            Prim::Capsule { a, b, r } => (nalgebra::center(a, b), 0.5 * (b - a).norm() + r),
            Prim::Box { pose, half } => (Point3::from(pose.translation.vector), half.norm()),
        }
    }
    /// The bounding capsule of a box (see the module docs); capsules unchanged.
    fn as_capsule(&self) -> (Point3<f64>, Point3<f64>, f64) {
        match *self {
            Prim::Capsule { a, b, r } => (a, b, r),
            Prim::Box { pose, half } => {
                let (k, others) = if half.x >= half.y && half.x >= half.z {
                    (0, (half.y, half.z))
                } else if half.y >= half.z {
                    (1, (half.x, half.z))
                } else {
                    (2, (half.x, half.y))
                };
                let mut axis = Vector3::zeros();
                axis[k] = half[k];
                let a = pose * Point3::from(-axis);
                let b = pose * Point3::from(axis);
                (a, b, others.0.hypot(others.1))
            }
        }
    }
    fn transformed(&self, t: &Isometry3<f64>) -> Prim {
        match *self {
            Prim::Capsule { a, b, r } => Prim::Capsule {
                a: t * a,
                b: t * b,
                r,
            },
            Prim::Box { pose, half } => Prim::Box {
                pose: t * pose,
                half,
            },
        }
    }
    fn volume_proxy(&self) -> f64 {
        match self {
            Prim::Capsule { a, b, r } => r * r * ((b - a).norm() + r),
            Prim::Box { half, .. } => half.x * half.y * half.z,
        }
    }
}

/// Closest distance between segments `p1-q1` and `p2-q2` (Ericson, Real-Time Collision
/// Detection §5.1.9).
fn segment_segment(p1: &Point3<f64>, q1: &Point3<f64>, p2: &Point3<f64>, q2: &Point3<f64>) -> f64 {
    let d1 = q1 - p1;
    let d2 = q2 - p2;
    let r = p1 - p2;
    let a = d1.dot(&d1);
    let e = d2.dot(&d2);
    let f = d2.dot(&r);
    let eps = 1e-15;
    let (s, t);
    if a <= eps && e <= eps {
        return r.norm();
    }
    if a <= eps {
        s = 0.0;
        t = (f / e).clamp(0.0, 1.0);
    } else {
        let c = d1.dot(&r);
        if e <= eps {
            t = 0.0;
            s = (-c / a).clamp(0.0, 1.0);
        } else {
            let b = d1.dot(&d2);
            let denom = a * e - b * b;
            let mut s0 = if denom > eps {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let mut t0 = (b * s0 + f) / e;
            if t0 < 0.0 {
                t0 = 0.0;
                s0 = (-c / a).clamp(0.0, 1.0);
            } else if t0 > 1.0 {
                t0 = 1.0;
                s0 = ((b - c) / a).clamp(0.0, 1.0);
            }
            s = s0;
            t = t0;
        }
    }
    ((p1 + d1 * s) - (p2 + d2 * t)).norm()
}

/// Distance from a point (box frame) to an axis-aligned box of half sides `half` (0 inside).
fn point_box(p: &Vector3<f64>, half: &Vector3<f64>) -> f64 {
    let dx = (p.x.abs() - half.x).max(0.0);
    let dy = (p.y.abs() - half.y).max(0.0);
    let dz = (p.z.abs() - half.z).max(0.0);
    (dx * dx + dy * dy + dz * dz).sqrt()
}

/// Distance from segment `a-b` to the box (convex in the segment parameter: golden section).
fn segment_box(
    a: &Point3<f64>,
    b: &Point3<f64>,
    pose: &Isometry3<f64>,
    half: &Vector3<f64>,
) -> f64 {
    let inv = pose.inverse();
    let la = (inv * a).coords;
    let lb = (inv * b).coords;
    let f = |t: f64| point_box(&(la + (lb - la) * t), half);
    let g = 0.618_033_988_749_894_9;
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    let mut x1 = hi - g * (hi - lo);
    let mut x2 = lo + g * (hi - lo);
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..48 {
        if f1 <= f2 {
            hi = x2;
            x2 = x1;
            f2 = f1;
            x1 = hi - g * (hi - lo);
            f1 = f(x1);
        } else {
            lo = x1;
            x1 = x2;
            f1 = f2;
            x2 = lo + g * (hi - lo);
            f2 = f(x2);
        }
        if f1 == 0.0 || f2 == 0.0 {
            return 0.0;
        }
    }
    f1.min(f2).min(f(0.0)).min(f(1.0))
}

/// Signed-ish distance between two primitives (world frame): negative when they intersect
/// (capsule pairs: the exact penetration depth; pairs with a box: minus the capsule radius).
fn distance(p: &Prim, q: &Prim) -> f64 {
    match (p, q) {
        (Prim::Capsule { a, b, r }, Prim::Capsule { a: c, b: d, r: s }) => {
            segment_segment(a, b, c, d) - r - s
        }
        (Prim::Capsule { a, b, r }, Prim::Box { pose, half })
        | (Prim::Box { pose, half }, Prim::Capsule { a, b, r }) => {
            segment_box(a, b, pose, half) - r
        }
        (Prim::Box { .. }, Prim::Box { .. }) => {
            let (small, big) = if p.volume_proxy() <= q.volume_proxy() {
                (p, q)
            } else {
                (q, p)
            };
            let (a, b, r) = small.as_capsule();
            match big {
                Prim::Box { pose, half } => segment_box(&a, &b, pose, half) - r,
                Prim::Capsule { .. } => f64::INFINITY,
            }
        }
    }
}

/// A colliding pair of links, by name.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CollidingPair {
    /// First link.
    pub a: String,
    /// Second link.
    pub b: String,
}

/// Self-collision checker for a whole robot model (see the module docs).
#[derive(Debug, Clone)]
pub struct SelfCollision {
    link_names: Vec<String>,
    /// Parent link and joint of each link (`None` for the root).
    parent: Vec<Option<(usize, usize)>>,
    /// Links in an order where parents come first.
    order: Vec<usize>,
    joints: Vec<robot_model::JointModel>,
    /// Primitives per link, link frame.
    prims: Vec<Vec<Prim>>,
    /// Pairs of links checked (see the module docs).
    pairs: Vec<(usize, usize)>,
    poses: Vec<Isometry3<f64>>,
    world: Vec<Vec<Prim>>,
}

impl SelfCollision {
    /// Builds the checker and its list of checked pairs.
    pub fn new(model: &RobotModel) -> Self {
        let nl = model.links.len();
        let parent: Vec<Option<(usize, usize)>> = model
            .links
            .iter()
            .map(|l| l.parent_joint.map(|j| (model.joints[j].parent, j)))
            .collect();
        // Topological order: breadth first from the root.
        let mut order = vec![model.root];
        let mut k = 0;
        while k < order.len() {
            let cur = order[k];
            for (li, p) in parent.iter().enumerate() {
                if matches!(p, Some((pl, _)) if *pl == cur) {
                    order.push(li);
                }
            }
            k += 1;
        }
        let prims: Vec<Vec<Prim>> = model
            .links
            .iter()
            .map(|l| {
                l.collision
                    .iter()
                    .filter_map(|c| {
                        let o = &c.origin.to_iso();
                        match c.shape {
                            Shape::Sphere { radius_m } if radius_m > MARKER_RADIUS_M => {
                                let p = Point3::from(o.translation.vector);
                                Some(Prim::Capsule {
                                    a: p,
                                    b: p,
                                    r: radius_m,
                                })
                            }
                            Shape::Cylinder { radius_m, length_m }
                            | Shape::Capsule { radius_m, length_m } => Some(Prim::Capsule {
                                a: o * Point3::new(0.0, 0.0, -0.5 * length_m),
                                b: o * Point3::new(0.0, 0.0, 0.5 * length_m),
                                r: radius_m,
                            }),
                            Shape::Box { size_m } => Some(Prim::Box {
                                pose: *o,
                                half: Vector3::new(size_m[0], size_m[1], size_m[2]) * 0.5,
                            }),
                            _ => None,
                        }
                    })
                    .collect()
            })
            .collect();
        // Rigid groups: a link belongs to the group of its nearest ancestor through movable
        // joints only.
        let mut group = vec![usize::MAX; nl];
        for &li in &order {
            group[li] = match parent[li] {
                Some((pl, j)) if !model.joints[j].kind.is_movable() => group[pl],
                _ => li,
            };
        }
        let mut me = Self {
            link_names: model.links.iter().map(|l| l.name.clone()).collect(),
            parent,
            order,
            joints: model.joints.clone(),
            prims,
            pairs: Vec::new(),
            poses: vec![Isometry3::identity(); nl],
            world: vec![Vec::new(); nl],
        };
        let reference: Vec<f64> = model
            .joints
            .iter()
            .map(|j| 0.0_f64.clamp(j.limits.lower, j.limits.upper))
            .collect();
        me.update(&reference);
        let mut pairs = Vec::new();
        for a in 0..nl {
            for b in (a + 1)..nl {
                if me.prims[a].is_empty() || me.prims[b].is_empty() || group[a] == group[b] {
                    continue;
                }
                let adjacent = matches!(me.parent[a], Some((p, _)) if p == b)
                    || matches!(me.parent[b], Some((p, _)) if p == a);
                if adjacent || me.link_distance(a, b) < DEFAULT_CONTACT_M {
                    continue;
                }
                pairs.push((a, b));
            }
        }
        me.pairs = pairs;
        me
    }

    /// Number of link pairs checked.
    pub fn pair_count(&self) -> usize {
        self.pairs.len()
    }

    /// Whether links `a` and `b` (by name) are a checked pair.
    pub fn checks_pair(&self, a: &str, b: &str) -> bool {
        let find = |n: &str| self.link_names.iter().position(|l| l == n);
        match (find(a), find(b)) {
            (Some(x), Some(y)) => self
                .pairs
                .iter()
                .any(|&(p, q)| (p, q) == (x.min(y), x.max(y))),
            _ => false,
        }
    }

    /// Link poses (model root frame) and world primitives for full joint values `q` (one value
    /// per model joint, in `RobotModel::joints` order; fixed joints ignore theirs).
    fn update(&mut self, q: &[f64]) {
        for &li in &self.order {
            self.poses[li] = match self.parent[li] {
                None => Isometry3::identity(),
                Some((pl, j)) => {
                    self.poses[pl] * self.joints[j].transform(q.get(j).copied().unwrap_or(0.0))
                }
            };
            let pose = self.poses[li];
            let (prims, world) = (&self.prims[li], &mut self.world[li]);
            world.clear();
            world.extend(prims.iter().map(|p| p.transformed(&pose)));
        }
    }

    /// Smallest distance between two links' primitives (after [`SelfCollision::update`]).
    fn link_distance(&self, a: usize, b: usize) -> f64 {
        let mut best = f64::INFINITY;
        for p in &self.world[a] {
            let (cp, rp) = p.bounding();
            for q in &self.world[b] {
                let (cq, rq) = q.bounding();
                let gap = (cp - cq).norm() - rp - rq;
                if gap >= best {
                    continue;
                }
                best = best.min(distance(p, q));
            }
        }
        best
    }

    /// The first intersecting checked pair for full joint values `q` (model joint order), among
    /// pairs where at least one link has `moving[link]` true (`None`: all pairs).
    pub fn first_collision(
        &mut self,
        q: &[f64],
        moving: Option<&[bool]>,
    ) -> Option<(usize, usize)> {
        self.update(q);
        for &(a, b) in &self.pairs {
            if let Some(m) = moving
                && !m.get(a).copied().unwrap_or(true)
                && !m.get(b).copied().unwrap_or(true)
            {
                continue;
            }
            for p in &self.world[a] {
                let (cp, rp) = p.bounding();
                for r in &self.world[b] {
                    let (cr, rr) = r.bounding();
                    if (cp - cr).norm() >= rp + rr {
                        continue;
                    }
                    if distance(p, r) < 0.0 {
                        return Some((a, b));
                    }
                }
            }
        }
        None
    }

    /// [`SelfCollision::first_collision`] over all pairs, with link names.
    pub fn colliding_pair(&mut self, q: &[f64]) -> Option<CollidingPair> {
        self.first_collision(q, None).map(|(a, b)| CollidingPair {
            a: self.link_names[a].clone(),
            b: self.link_names[b].clone(),
        })
    }

    /// Per link, whether its pose depends on one of the given model joints (the links that a
    /// chain moves).
    pub fn moved_by(&self, joints: &[usize]) -> Vec<bool> {
        let mut moving = vec![false; self.link_names.len()];
        for &li in &self.order {
            if let Some((pl, j)) = self.parent[li] {
                moving[li] = moving[pl] || joints.contains(&j);
            }
        }
        moving
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn loki() -> RobotModel {
        RobotModel::from_urdf_file(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../models/loki.urdf"
        ))
        .unwrap()
    }

    #[test]
    fn loki_pair_list_follows_the_rules() {
        let model = loki();
        let mut c = SelfCollision::new(&model);
        // Checked: parts that can really meet.
        for (a, b) in [
            ("left_hand", "torso"),
            ("left_forearm", "torso"),
            ("left_hand", "right_hand"),
            ("left_hand", "head"),
            ("left_hand", "base_link"),
            ("left_finger_distal", "torso"),
            ("right_forearm", "left_forearm"),
        ] {
            assert!(c.checks_pair(a, b), "{a} - {b}");
        }
        // Not checked: adjacent, rigidly attached, in contact at home, markers.
        for (a, b) in [
            ("left_upper_arm", "left_elbow_link"),
            ("base_link", "torso"),
            ("left_upper_arm", "torso"),
            ("left_hand_center", "torso"),
        ] {
            assert!(!c.checks_pair(a, b), "{a} - {b}");
        }
        assert!(c.pair_count() > 300, "{}", c.pair_count());
        // Home is collision-free; the left hand pushed into the torso is not.
        let mut q: Vec<f64> = model
            .joints
            .iter()
            .map(|j| 0.0_f64.clamp(j.limits.lower, j.limits.upper))
            .collect();
        assert_eq!(c.colliding_pair(&q), None);
        let idx = |n: &str| model.joints.iter().position(|j| j.name == n).unwrap();
        // Upper arm down and rolled in, elbow at 90° (forearm forward), shoulder yaw swinging the
        // forearm inwards through the chest (one of the two yaw signs points inwards).
        q[idx("left_shoulder_roll")] = -0.3;
        q[idx("left_elbow")] = -1.57;
        let mut hit = None;
        for yaw in [1.5, -1.5] {
            q[idx("left_shoulder_yaw")] = yaw;
            hit = hit.or(c.colliding_pair(&q));
        }
        let hit = hit.expect("forearm across the chest");
        assert!(hit.b == "torso" || hit.a == "torso", "{hit:?}");
    }

    #[test]
    fn segment_distances_match_hand_computed_cases() {
        let p = |x, y, z| Point3::new(x, y, z);
        // Parallel segments 1 apart.
        let d = segment_segment(
            &p(0., 0., 0.),
            &p(1., 0., 0.),
            &p(0., 1., 0.),
            &p(1., 1., 0.),
        );
        assert!((d - 1.0).abs() < 1e-12);
        // Crossing segments (skew by 0.5 in z).
        let d = segment_segment(
            &p(-1., 0., 0.),
            &p(1., 0., 0.),
            &p(0., -1., 0.5),
            &p(0., 1., 0.5),
        );
        assert!((d - 0.5).abs() < 1e-12);
        // Point to box: 0.3 beyond the +x face.
        let h = Vector3::new(0.5, 0.5, 0.5);
        assert!((point_box(&Vector3::new(0.8, 0.0, 0.0), &h) - 0.3).abs() < 1e-12);
        // Segment passing over a box corner region.
        let d = segment_box(
            &p(-2., 0., 1.0),
            &p(2., 0., 1.0),
            &Isometry3::identity(),
            &h,
        );
        assert!((d - 0.5).abs() < 1e-7, "{d}");
        // Segment through the box.
        let d = segment_box(
            &p(-2., 0.1, 0.0),
            &p(2., 0.1, 0.0),
            &Isometry3::identity(),
            &h,
        );
        assert_eq!(d, 0.0);
    }
}
