//! Reading URDF: poses and geometry from urdf-rs, XML syntax errors located, and robocog's
//! `<robocog_camera>` elements.

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

/// Parses `key="value"` attributes of every `<robocog_camera .../>` element in raw URDF text.
/// XML comments (`<!-- ... -->`) are skipped.
pub(super) fn parse_cameras(text: &str) -> Result<Vec<CameraIntrinsics>> {
    let mut uncommented = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(start) = rest.find("<!--") {
        uncommented.push_str(&rest[..start]);
        match rest[start..].find("-->") {
            Some(end) => rest = &rest[start + end + 3..],
            None => return Err(ModelError::MalformedUrdf("unterminated XML comment".into())),
        }
    }
    uncommented.push_str(rest);
    let mut out = Vec::new();
    let mut rest = uncommented.as_str();
    while let Some(start) = rest.find("<robocog_camera") {
        let after = &rest[start + "<robocog_camera".len()..];
        let end = after.find('>').ok_or_else(|| {
            ModelError::MalformedUrdf("unterminated <robocog_camera> element".into())
        })?;
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
                    ModelError::MalformedUrdf(format!(
                        "<robocog_camera>: attribute `{key}` is not quoted"
                    ))
                })?;
            let v = &v[1..];
            let close = v.find(quote).ok_or_else(|| {
                ModelError::MalformedUrdf(format!(
                    "<robocog_camera>: attribute `{key}` is unterminated"
                ))
            })?;
            attrs.insert(key, &v[..close]);
            s = &v[close + 1..];
        }
        let get = |k: &str| {
            attrs.get(k).copied().ok_or_else(|| {
                ModelError::InvalidModel(format!("<robocog_camera> is missing attribute `{k}`"))
            })
        };
        let num = |k: &str| -> Result<f64> {
            let v = get(k)?;
            v.trim()
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| {
                    ModelError::InvalidModel(format!(
                        "<robocog_camera> attribute `{k}`=`{v}` is not a number"
                    ))
                })
        };
        let int = |k: &str| -> Result<u32> {
            let v = get(k)?;
            v.trim().parse::<u32>().map_err(|_| {
                ModelError::InvalidModel(format!(
                    "<robocog_camera> attribute `{k}`=`{v}` is not a size"
                ))
            })
        };
        out.push(CameraIntrinsics {
            name: get("name")?.to_string(),
            frame: get("frame")?.to_string(),
            width: int("width")?,
            height: int("height")?,
            fx: num("fx")?,
            fy: num("fy")?,
            cx: num("cx")?,
            cy: num("cy")?,
            min_range_m: num("min_range_m")?,
            max_range_m: num("max_range_m")?,
        });
        rest = &after[end..];
    }
    Ok(out)
}
