//! The RoboCup SPL field model (`models/spl_field.toml`) and how it enters the scene graph.
//!
//! The file is in millimetres, like the SPL rule book and the Nao UDP protocol; the graph works in
//! metres. Frame `field`: origin at the centre spot, x towards the opponent goal, y to the left
//! seen from our own goal, z up; the field plane is z = 0.

use std::path::Path;

use serde::Deserialize;

use crate::error::{DrError, Result};
use crate::graph::SceneGraph;
use crate::types::{AttrValue, Edge, NodeSpec, NodeType, Stamp, StructuralChange, Transform, attr};

/// A landmark of the field file.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LandmarkSpec {
    /// Node name.
    pub name: String,
    /// `goalpost`, `spot` or `penalty_mark`.
    pub class: String,
    /// Position on the field plane (mm).
    pub x_mm: f64,
    /// Position on the field plane (mm).
    pub y_mm: f64,
}

/// The field model (all lengths in mm). Field names follow `models/spl_field.toml`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(missing_docs)]
pub struct FieldModel {
    pub name: String,
    pub length_mm: f64,
    pub width_mm: f64,
    pub line_width_mm: f64,
    pub border_strip_mm: f64,
    pub center_circle_diameter_mm: f64,
    pub penalty_mark_distance_mm: f64,
    pub penalty_area_length_mm: f64,
    pub penalty_area_width_mm: f64,
    pub goal_area_length_mm: f64,
    pub goal_area_width_mm: f64,
    pub goal_inner_width_mm: f64,
    pub goalpost_diameter_mm: f64,
    pub goal_height_mm: f64,
    pub goal_depth_mm: f64,
    pub ball_diameter_mm: f64,
    pub landmarks: Vec<LandmarkSpec>,
}

/// A straight field line segment on the field plane (mm), from `a` to `b`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineSegment {
    /// Start (x, y) mm.
    pub a: [f64; 2],
    /// End (x, y) mm.
    pub b: [f64; 2],
}

impl FieldModel {
    /// Parses TOML text; unknown keys, missing keys and non-positive dimensions are errors.
    pub fn from_toml_str(text: &str) -> Result<Self> {
        let f: FieldModel =
            toml::from_str(text).map_err(|e| DrError::InvalidField(e.to_string()))?;
        let dims = [
            ("length_mm", f.length_mm),
            ("width_mm", f.width_mm),
            ("line_width_mm", f.line_width_mm),
            ("penalty_area_length_mm", f.penalty_area_length_mm),
            ("penalty_area_width_mm", f.penalty_area_width_mm),
            ("goal_inner_width_mm", f.goal_inner_width_mm),
            ("goalpost_diameter_mm", f.goalpost_diameter_mm),
            ("ball_diameter_mm", f.ball_diameter_mm),
        ];
        for (k, v) in dims {
            if !(v.is_finite() && v > 0.0) {
                return Err(DrError::InvalidField(format!(
                    "{k} must be a positive number, got {v}"
                )));
            }
        }
        for l in &f.landmarks {
            if !(l.x_mm.is_finite() && l.y_mm.is_finite()) {
                return Err(DrError::InvalidField(format!(
                    "landmark `{}`: position not finite",
                    l.name
                )));
            }
        }
        Ok(f)
    }

    /// Reads a TOML file.
    pub fn from_file(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| DrError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Self::from_toml_str(&text)
    }

    /// Half length and half width (m): the field is `|x| <= hx, |y| <= hy` in the field frame.
    pub fn half_extents_m(&self) -> (f64, f64) {
        (self.length_mm / 2000.0, self.width_mm / 2000.0)
    }

    /// The straight lines (centre lines of the painted lines, mm): touch lines, goal lines, halfway
    /// line, both penalty areas and goal areas. The centre circle is not included.
    pub fn lines(&self) -> Vec<LineSegment> {
        let (hx, hy) = (self.length_mm / 2.0, self.width_mm / 2.0);
        let mut v = vec![
            LineSegment {
                a: [-hx, hy],
                b: [hx, hy],
            },
            LineSegment {
                a: [-hx, -hy],
                b: [hx, -hy],
            },
            LineSegment {
                a: [-hx, -hy],
                b: [-hx, hy],
            },
            LineSegment {
                a: [hx, -hy],
                b: [hx, hy],
            },
            LineSegment {
                a: [0.0, -hy],
                b: [0.0, hy],
            },
        ];
        for s in [-1.0, 1.0] {
            for (len, wid) in [
                (self.penalty_area_length_mm, self.penalty_area_width_mm),
                (self.goal_area_length_mm, self.goal_area_width_mm),
            ] {
                let (gx, ix, w) = (s * hx, s * (hx - len), wid / 2.0);
                v.push(LineSegment {
                    a: [gx, w],
                    b: [ix, w],
                });
                v.push(LineSegment {
                    a: [gx, -w],
                    b: [ix, -w],
                });
                v.push(LineSegment {
                    a: [ix, -w],
                    b: [ix, w],
                });
            }
        }
        v
    }

    /// Adds a `field` node (fixed, at `pose` under `parent`) and one landmark node per landmark.
    pub fn add_to_graph(
        &self,
        g: &mut SceneGraph,
        parent: &str,
        pose: Transform,
        stamp: Stamp,
    ) -> Result<()> {
        let field = NodeSpec {
            edge: Edge::Fixed { origin: pose },
            ..NodeSpec::free("field", NodeType::Field, parent, Transform::default())
        }
        .with_attr(attr::LENGTH_M, AttrValue::Float(self.length_mm / 1000.0))
        .with_attr(attr::WIDTH_M, AttrValue::Float(self.width_mm / 1000.0));
        let mut specs = vec![field];
        for l in &self.landmarks {
            let t = if l.class == "goalpost" {
                NodeType::Goalpost
            } else {
                NodeType::Landmark
            };
            let mut s = NodeSpec {
                edge: Edge::Fixed {
                    origin: Transform::from_translation(l.x_mm / 1000.0, l.y_mm / 1000.0, 0.0),
                },
                ..NodeSpec::free(&l.name, t, "field", Transform::default())
            }
            .with_attr("class", AttrValue::Text(l.class.clone()));
            if t == NodeType::Goalpost {
                s = s.with_attr(
                    attr::RADIUS_M,
                    AttrValue::Float(self.goalpost_diameter_mm / 2000.0),
                );
            }
            specs.push(s);
        }
        for s in specs {
            g.propose(StructuralChange::AddNode(Box::new(s)), stamp)
                .map_err(|r| DrError::Rejected(Box::new(r)))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spl() -> FieldModel {
        FieldModel::from_file(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../models/spl_field.toml"
        ))
        .unwrap()
    }

    #[test]
    fn spl_field_dimensions_and_landmarks() {
        let f = spl();
        assert_eq!((f.length_mm, f.width_mm), (9000.0, 6000.0));
        assert_eq!(f.half_extents_m(), (4.5, 3.0));
        let posts: Vec<_> = f
            .landmarks
            .iter()
            .filter(|l| l.class == "goalpost")
            .collect();
        assert_eq!(posts.len(), 4);
        for p in posts {
            assert_eq!(p.x_mm.abs(), 4500.0);
            // Inner width 1500 between post faces, 100 mm posts: centres at +-800 mm.
            assert_eq!(
                p.y_mm.abs(),
                (f.goal_inner_width_mm + f.goalpost_diameter_mm) / 2.0
            );
        }
        assert_eq!(f.lines().len(), 5 + 12);
        let mut g = SceneGraph::new();
        f.add_to_graph(&mut g, "world", Transform::default(), Stamp(0))
            .unwrap();
        let p = g
            .transform("world", "opponent_goalpost_left", crate::graph::At::Latest)
            .unwrap();
        assert_eq!(p.translation.vector, nalgebra::Vector3::new(4.5, 0.8, 0.0));
    }

    #[test]
    fn bad_field_files_are_rejected() {
        assert!(matches!(
            FieldModel::from_toml_str("name = 3"),
            Err(DrError::InvalidField(_))
        ));
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../models/spl_field.toml"
        ))
        .unwrap();
        let typo = text.replace("width_mm = 6000.0", "widht_mm = 6000.0");
        assert!(matches!(
            FieldModel::from_toml_str(&typo),
            Err(DrError::InvalidField(_))
        ));
        let neg = text.replace("length_mm = 9000.0", "length_mm = -1.0");
        assert!(matches!(
            FieldModel::from_toml_str(&neg),
            Err(DrError::InvalidField(_))
        ));
    }
}
