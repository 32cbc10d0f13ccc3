//! Reading URDF: poses and geometry from urdf-rs, XML syntax errors located, and robocog's
//! `<robocog_camera>` and `<robocog_stewart_neck>` elements.

use super::*;

pub(super) fn pose_to_iso(p: &urdf_rs::Pose) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(p.xyz[0], p.xyz[1], p.xyz[2]),
        UnitQuaternion::from_euler_angles(p.rpy[0], p.rpy[1], p.rpy[2]),
    )
}

pub(super) fn convert_geometry(g: &urdf_rs::Geometry) -> Shape {
    match g {
        urdf_rs::Geometry::Box { size } => Shape::Box { size_m: size.0 },
        urdf_rs::Geometry::Cylinder { radius, length } => Shape::Cylinder {
            radius_m: *radius,
            length_m: *length,
        },
        urdf_rs::Geometry::Capsule { radius, length } => Shape::Capsule {
            radius_m: *radius,
            length_m: *length,
        },
        urdf_rs::Geometry::Sphere { radius } => Shape::Sphere { radius_m: *radius },
        urdf_rs::Geometry::Mesh { filename, .. } => Shape::Mesh {
            filename: filename.clone(),
        },
    }
}

/// The first XML syntax error of `text` with its `line:column` (1-based), if any.
pub(super) fn xml_syntax_error(text: &str) -> Option<String> {
    for ev in xml::reader::EventReader::from_str(text) {
        match ev {
            Ok(xml::reader::XmlEvent::EndDocument) => return None,
            Ok(_) => {}
            Err(e) => return Some(e.to_string()),
        }
    }
    None
}

/// The `key="value"` attributes of one robocog element (`<robocog_camera .../>`, ...).
pub(super) struct Element<'a> {
    tag: &'static str,
    attrs: HashMap<&'a str, &'a str>,
}

impl Element<'_> {
    pub(super) fn get(&self, k: &str) -> Result<&str> {
        self.attrs.get(k).copied().ok_or_else(|| {
            ModelError::InvalidModel(format!("<{}> is missing attribute `{k}`", self.tag))
        })
    }

    pub(super) fn num(&self, k: &str) -> Result<f64> {
        let v = self.get(k)?;
        v.trim()
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| {
                ModelError::InvalidModel(format!(
                    "<{}> attribute `{k}`=`{v}` is not a number",
                    self.tag
                ))
            })
    }

    pub(super) fn int(&self, k: &str) -> Result<u32> {
        let v = self.get(k)?;
        v.trim().parse::<u32>().map_err(|_| {
            ModelError::InvalidModel(format!(
                "<{}> attribute `{k}`=`{v}` is not a size",
                self.tag
            ))
        })
    }
}

/// Every `<tag .../>` element of raw URDF text, with its `key="value"` attributes. XML comments
/// (`<!-- ... -->`) are skipped. URDF parsers (urdf-rs, urdfdom) ignore these elements.
pub(super) fn parse_elements<'a>(text: &'a str, tag: &'static str) -> Result<Vec<Element<'a>>> {
    let mut out = Vec::new();
    let mut rest = text;
    let open = format!("<{tag}");
    loop {
        let comment = rest.find("<!--");
        let element = rest.find(&open);
        let start = match (comment, element) {
            (Some(c), Some(e)) if c < e => {
                let end = rest[c..]
                    .find("-->")
                    .ok_or_else(|| ModelError::MalformedUrdf("unterminated XML comment".into()))?;
                rest = &rest[c + end + 3..];
                continue;
            }
            (_, Some(e)) => e,
            (_, None) => return Ok(out),
        };
        let after = &rest[start + open.len()..];
        let end = after
            .find('>')
            .ok_or_else(|| ModelError::MalformedUrdf(format!("unterminated <{tag}> element")))?;
        let body = after[..end].trim_end_matches('/');
        let mut attrs: HashMap<&str, &str> = HashMap::new();
        let mut s = body;
        while let Some(eq) = s.find('=') {
            let key = s[..eq].trim();
            let v = s[eq + 1..].trim_start();
            let quote = v
                .chars()
                .next()
                .filter(|c| *c == '"' || *c == '\'')
                .ok_or_else(|| {
                    ModelError::MalformedUrdf(format!("<{tag}>: attribute `{key}` is not quoted"))
                })?;
            let v = &v[1..];
            let close = v.find(quote).ok_or_else(|| {
                ModelError::MalformedUrdf(format!("<{tag}>: attribute `{key}` is unterminated"))
            })?;
            attrs.insert(key, &v[..close]);
            s = &v[close + 1..];
        }
        out.push(Element { tag, attrs });
        rest = &after[end..];
    }
}

/// The `<robocog_camera .../>` elements of raw URDF text.
pub(super) fn parse_cameras(text: &str) -> Result<Vec<CameraIntrinsics>> {
    parse_elements(text, "robocog_camera")?
        .iter()
        .map(|e| {
            Ok(CameraIntrinsics {
                name: e.get("name")?.to_string(),
                frame: e.get("frame")?.to_string(),
                width: e.int("width")?,
                height: e.int("height")?,
                fx: e.num("fx")?,
                fy: e.num("fy")?,
                cx: e.num("cx")?,
                cy: e.num("cy")?,
                min_range_m: e.num("min_range_m")?,
                max_range_m: e.num("max_range_m")?,
            })
        })
        .collect()
}

/// The `<robocog_stewart_neck .../>` element of raw URDF text, if any, checked against the
/// model's joints (`joints`: name and kind of every joint).
pub(super) fn parse_stewart_neck(
    text: &str,
    joints: &[JointModel],
) -> Result<Option<StewartNeckSpec>> {
    const TAG: &str = "robocog_stewart_neck";
    let elements = parse_elements(text, TAG)?;
    let e = match elements.as_slice() {
        [] => return Ok(None),
        [e] => e,
        _ => {
            return Err(ModelError::InvalidModel(format!(
                "{} <{TAG}> elements: a robot has one neck",
                elements.len()
            )));
        }
    };
    let invalid = |what: String| ModelError::InvalidModel(format!("<{TAG}>: {what}"));
    let axis = |k: &str| -> Result<String> {
        let name = e.get(k)?;
        match joints.iter().find(|j| j.name == name) {
            Some(j) if j.kind == JointKind::Revolute => Ok(name.to_string()),
            Some(_) => Err(invalid(format!("{k}=`{name}` must be a revolute joint"))),
            None => Err(invalid(format!("{k}=`{name}` is not a joint of the model"))),
        }
    };
    let (pitch, roll, yaw) = (axis("pitch")?, axis("roll")?, axis("yaw")?);
    if pitch == roll || roll == yaw || pitch == yaw {
        return Err(invalid(
            "pitch, roll and yaw must be three different joints".into(),
        ));
    }
    let legs: Vec<&str> = e.get("legs")?.split_whitespace().collect();
    let legs: [String; 3] = match legs.as_slice() {
        [a, b, c] if a != b && b != c && a != c => [a.to_string(), b.to_string(), c.to_string()],
        _ => {
            return Err(invalid(format!(
                "legs=`{}` must name three different legs, separated by spaces",
                e.get("legs")?
            )));
        }
    };
    if let Some(l) = legs.iter().find(|l| joints.iter().any(|j| &j.name == *l)) {
        return Err(invalid(format!(
            "leg `{l}` is a joint of the URDF: the legs are the platform's actuators, not joints of the kinematic tree"
        )));
    }
    let positive = |k: &str| -> Result<f64> {
        let v = e.num(k)?;
        if v > 0.0 {
            Ok(v)
        } else {
            Err(invalid(format!("{k} must be > 0, got {v}")))
        }
    };
    let spec = StewartNeckSpec {
        pitch,
        roll,
        yaw,
        legs,
        base_radius_m: positive("base_radius_m")?,
        platform_radius_m: positive("platform_radius_m")?,
        pivot_height_m: positive("pivot_height_m")?,
        twist_rad: e.num("twist_deg")?.to_radians(),
        min_length_m: positive("min_length_m")?,
        max_length_m: positive("max_length_m")?,
        leg_velocity_m_s: positive("leg_velocity_m_s")?,
    };
    if spec.min_length_m >= spec.max_length_m {
        return Err(invalid(format!(
            "min_length_m {} must be below max_length_m {}",
            spec.min_length_m, spec.max_length_m
        )));
    }
    Ok(Some(spec))
}

#[cfg(test)]
mod tests {
    use super::*;

    const NECK: &str = r#"<robocog_stewart_neck pitch="p" roll="r" yaw="y" legs="l0 l1 l2" base_radius_m="0.07" platform_radius_m="0.05" pivot_height_m="0.1" twist_deg="60" min_length_m="0.08" max_length_m="0.155" leg_velocity_m_s="0.1"/>"#;

    /// A three-joint neck with `extra` inside the robot element.
    fn urdf(extra: &str) -> String {
        let joint = |name: &str, parent: &str, child: &str, kind: &str| {
            format!(
                r#"<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/><axis xyz="0 0 1"/><limit lower="-0.5" upper="0.5" velocity="1" effort="1"/></joint>"#
            )
        };
        format!(
            r#"<robot name="n"><link name="a"/><link name="b"/><link name="c"/><link name="d"/>{}{}{}{extra}</robot>"#,
            joint("p", "a", "b", "revolute"),
            joint("r", "b", "c", "revolute"),
            joint("y", "c", "d", "prismatic"),
        )
    }

    fn error(extra: &str) -> String {
        RobotModel::from_urdf_str(&urdf(extra))
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn loki_declares_its_stewart_neck() {
        let m = RobotModel::from_urdf_file(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../models/loki.urdf"
        ))
        .unwrap();
        let n = m
            .stewart_neck
            .expect("loki.urdf has a <robocog_stewart_neck>");
        assert_eq!(
            [n.pitch.as_str(), &n.roll, &n.yaw],
            ["neck_pitch", "neck_roll", "neck_yaw"]
        );
        assert_eq!(n.legs[2], "neck_leg_2");
        assert!((n.twist_rad - 60f64.to_radians()).abs() < 1e-12);
        assert!(n.min_length_m < n.max_length_m);
    }

    #[test]
    fn no_element_means_ideal_joints_and_comments_are_skipped() {
        let m = RobotModel::from_urdf_str(&urdf(&format!("<!-- {NECK} -->"))).unwrap();
        assert_eq!(m.stewart_neck, None);
    }

    #[test]
    fn a_bad_neck_element_is_refused_with_the_reason() {
        let e = error(NECK);
        assert!(e.contains("yaw=`y` must be a revolute joint"), "{e}");
        let fixed = NECK.replace(r#"yaw="y""#, r#"yaw="r""#);
        let e = error(&fixed);
        assert!(e.contains("three different joints"), "{e}");
        let unknown = NECK.replace(r#"yaw="y""#, r#"yaw="neck_yaw""#);
        assert!(error(&unknown).contains("`neck_yaw` is not a joint of the model"));
        let ok = NECK
            .replace(r#"yaw="y""#, r#"yaw="p""#)
            .replace(r#"pitch="p""#, r#"pitch="b""#);
        assert!(error(&ok).contains("pitch=`b` is not a joint"));
        let legs = NECK
            .replace(r#"yaw="y""#, r#"yaw="x""#)
            .replace("l0 l1 l2", "l0 l1");
        assert!(
            error(&legs).contains("is not a joint"),
            "the axis is checked first"
        );
    }

    /// A neck whose pitch, roll and yaw are the revolute joints p, r and a new one, q.
    fn valid(neck: &str) -> String {
        let q = r#"<link name="e"/><joint name="q" type="revolute"><parent link="d"/><child link="e"/><axis xyz="0 0 1"/><limit lower="-0.5" upper="0.5" velocity="1" effort="1"/></joint>"#;
        format!("{q}{}", neck.replace(r#"yaw="y""#, r#"yaw="q""#))
    }

    #[test]
    fn the_neck_numbers_and_legs_are_checked() {
        let m = RobotModel::from_urdf_str(&urdf(&valid(NECK))).unwrap();
        assert_eq!(m.stewart_neck.unwrap().legs[0], "l0");
        for (from, to, says) in [
            ("l0 l1 l2", "l0 l1", "three different legs"),
            ("l0 l1 l2", "l0 l1 l1", "three different legs"),
            ("l0 l1 l2", "l0 l1 p", "leg `p` is a joint of the URDF"),
            (
                r#"min_length_m="0.08""#,
                r#"min_length_m="0.2""#,
                "must be below",
            ),
            (
                r#"base_radius_m="0.07""#,
                r#"base_radius_m="-1""#,
                "must be > 0",
            ),
            (
                r#"twist_deg="60""#,
                r#"twist_deg="sixty""#,
                "is not a number",
            ),
            (
                r#" leg_velocity_m_s="0.1""#,
                "",
                "missing attribute `leg_velocity_m_s`",
            ),
        ] {
            let e = error(&valid(&NECK.replace(from, to)));
            assert!(e.contains(says), "{to}: {e}");
        }
        let e = error(&valid(&format!("{NECK}{NECK}")));
        assert!(e.contains("a robot has one neck"), "{e}");
    }
}
