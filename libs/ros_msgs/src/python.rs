//! The Python classes of every message type (`python/robocog/msg.py`), written from the same
//! walk of the Rust types as the ROS 2 definitions ([`crate::probe`]): one dataclass per struct,
//! with its fields in wire order and their type hints; no hand-written mirror.
//!
//! The classes hold what serde sees, so the Python runtime (`python/src`) builds them from a
//! decoded message by the struct's serde name, and encodes them back through the Rust type:
//!
//! - integers are `int`, floats `float`, text `str`, byte blocks `bytes` (a received frame's are
//!   `memoryview`s of the sample, see `robocog.images`), sequences and fixed arrays `list`;
//! - an enum whose variants carry nothing is a `Literal` of its variants' names; one whose
//!   variants carry data is serde's external tagging: the name of a unit variant, or a
//!   one-entry `dict` from the variant's name to its value;
//! - a newtype struct is its field's type.
//!
//! Every field has a default (zero, empty, the first variant; a quaternion's `w` is 1, as ROS 2
//! defines it), so `JointStates()` is a message.

use crate::probe::{Catalog, Container, Shape, Variant};
use std::collections::BTreeMap;
use std::fmt::Write;

/// Python's keywords: a field so named would be no attribute.
const KEYWORDS: &[&str] = &[
    "False", "None", "True", "and", "as", "assert", "async", "await", "break", "class", "continue",
    "def", "del", "elif", "else", "except", "finally", "for", "from", "global", "if", "import",
    "in", "is", "lambda", "nonlocal", "not", "or", "pass", "raise", "return", "try", "while",
    "with", "yield",
];

/// The source of `robocog/msg.py` for this build's message types; `Err` names a type that has
/// no Python form, and why.
pub fn module() -> Result<String, String> {
    let collect = crate::Collect::run();
    let mut roots = BTreeMap::new();
    for (ty, root) in collect.roots {
        roots.insert(ty, root.map_err(|why| format!("{ty}: {why}"))?);
    }
    let catalog = &collect.catalog;
    let mut out = String::new();
    out.push_str(HEAD);
    // Structs in an order where each class is defined after the classes its defaults build.
    let mut done: Vec<String> = Vec::new();
    for name in catalog.types.keys() {
        define(catalog, name, &mut done, &mut out, &mut Vec::new())?;
    }
    out.push_str("\n# Every message type by its name on the bus.\nTYPES: dict[str, type] = {\n");
    for (ty, root) in &roots {
        let _ = writeln!(out, "    {ty:?}: {},", py_name(catalog, root));
    }
    out.push_str("}\n\n# Every struct by its serde name (the decoder builds them by it).\n");
    out.push_str("CLASSES: dict[str, type] = {\n");
    for name in &done {
        if matches!(catalog.types.get(name), Some(Container::Struct(_))) {
            let _ = writeln!(out, "    {name:?}: {},", py_name(catalog, name));
        }
    }
    out.push_str("}\n");
    Ok(out)
}

const HEAD: &str = r#""""Every robocog message type as a Python dataclass.

Generated from the Rust message types by `robocog interface python`: do not edit. The suite
checks that this file is what the generator writes; after changing a message type, write it
again with `robocog interface python > libs/python/robocog/msg.py`.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Literal, Union

"#;

/// The Python name of a type: its serde name, or for a ROS 2 standard message
/// (`geometry_msgs/msg/Point`) its last part (`Point`), or `geometry_msgs_Point` when a type of
/// that name exists too.
fn py_name(catalog: &Catalog, name: &str) -> String {
    let Some((package, last)) = name.split_once('/').zip(name.rsplit_once('/')) else {
        return name.to_string();
    };
    let last = last.1;
    let clashes = catalog
        .types
        .keys()
        .filter(|k| *k != name && (k.as_str() == last || k.rsplit('/').next() == Some(last)))
        .count();
    if clashes == 0 {
        last.to_string()
    } else {
        format!("{}_{last}", package.0)
    }
}

/// Write the Python definition of `name` (and first those of the types its defaults build).
fn define(
    catalog: &Catalog,
    name: &str,
    done: &mut Vec<String>,
    out: &mut String,
    walking: &mut Vec<String>,
) -> Result<(), String> {
    if done.iter().any(|d| d == name) || walking.iter().any(|w| w == name) {
        return Ok(());
    }
    let container = catalog
        .types
        .get(name)
        .ok_or_else(|| format!("{name} was never described"))?;
    walking.push(name.to_string());
    for dep in dependencies(container) {
        define(catalog, &dep, done, out, walking)?;
    }
    walking.pop();
    let py = py_name(catalog, name);
    match container {
        Container::Struct(fields) => {
            let _ = writeln!(out, "\n@dataclasses.dataclass\nclass {py}:");
            if fields.is_empty() {
                out.push_str("    pass\n");
            }
            for (field, shape) in fields {
                if let Some(value) = ros_default(name, field) {
                    let _ = writeln!(out, "    {field}: {} = {value}", hint(catalog, shape));
                    continue;
                }
                if KEYWORDS.contains(&field.as_str()) {
                    return Err(format!(
                        "{py}.{field} is a Python keyword: no attribute can be named so"
                    ));
                }
                let _ = writeln!(
                    out,
                    "    {field}: {} = {}",
                    hint(catalog, shape),
                    default(catalog, shape, true)
                );
            }
        }
        Container::Newtype(inner) => {
            let _ = writeln!(out, "\n{py} = {}", hint(catalog, inner));
        }
        Container::Enum(variants) => {
            let all_unit = variants
                .iter()
                .all(|(_, v)| matches!(v, Some(Variant::Unit)));
            if all_unit {
                let names: Vec<String> = variants.iter().map(|(v, _)| format!("{v:?}")).collect();
                let _ = writeln!(out, "\n{py} = Literal[{}]", names.join(", "));
            } else {
                let _ = writeln!(
                    out,
                    "\n# An enum carrying data: a unit variant's name, or {{variant: value}}.\n{py} = Union[str, dict[str, Any]]"
                );
            }
        }
    }
    done.push(name.to_string());
    Ok(())
}

/// A default that ROS 2's own definition of a standard message gives a field (rclpy's too), where
/// it is not the zero: a quaternion is the identity rotation.
fn ros_default(message: &str, field: &str) -> Option<&'static str> {
    match (message, field) {
        ("geometry_msgs/msg/Quaternion", "w") => Some("1.0"),
        _ => None,
    }
}

/// The named types a container's definition refers to.
fn dependencies(c: &Container) -> Vec<String> {
    fn named(s: &Shape, out: &mut Vec<String>) {
        match s {
            Shape::Named(n) => out.push(n.clone()),
            Shape::Seq(i) | Shape::Array(i, _) => named(i, out),
            _ => {}
        }
    }
    let mut out = Vec::new();
    match c {
        Container::Struct(fields) => fields.iter().for_each(|(_, s)| named(s, &mut out)),
        Container::Newtype(s) => named(s, &mut out),
        Container::Enum(_) => {}
    }
    out
}

fn hint(catalog: &Catalog, shape: &Shape) -> String {
    match shape {
        Shape::Bool => "bool".into(),
        Shape::I8
        | Shape::I16
        | Shape::I32
        | Shape::I64
        | Shape::U8
        | Shape::U16
        | Shape::U32
        | Shape::U64 => "int".into(),
        Shape::F32 | Shape::F64 => "float".into(),
        Shape::Str => "str".into(),
        Shape::Bytes => "bytes".into(),
        Shape::Seq(inner) | Shape::Array(inner, _) => format!("list[{}]", hint(catalog, inner)),
        Shape::Named(n) => match catalog.types.get(n) {
            Some(Container::Newtype(inner)) => hint(catalog, inner),
            _ => py_name(catalog, n),
        },
        Shape::Unsupported(what) => format!("Any  # {what}"),
    }
}

/// A field's default: the zero of its type (`field` says whether it is written in a class body,
/// where mutable values need a factory).
fn default(catalog: &Catalog, shape: &Shape, field: bool) -> String {
    let factory = |expr: String| {
        if field {
            format!("dataclasses.field(default_factory=lambda: {expr})")
        } else {
            expr
        }
    };
    match shape {
        Shape::Bool => "False".into(),
        Shape::F32 | Shape::F64 => "0.0".into(),
        Shape::Str => "\"\"".into(),
        Shape::Bytes => "b\"\"".into(),
        Shape::Seq(_) => {
            if field {
                "dataclasses.field(default_factory=list)".into()
            } else {
                "[]".into()
            }
        }
        Shape::Array(inner, n) => factory(format!(
            "[{} for _ in range({n})]",
            default(catalog, inner, false)
        )),
        Shape::Named(n) => match catalog.types.get(n) {
            Some(Container::Struct(_)) => {
                let n = py_name(catalog, n);
                if field {
                    format!("dataclasses.field(default_factory={n})")
                } else {
                    format!("{n}()")
                }
            }
            Some(Container::Newtype(inner)) => default(catalog, inner, field),
            Some(Container::Enum(variants)) => match variants.first() {
                Some((v, Some(Variant::Unit))) | Some((v, None)) => format!("{v:?}"),
                Some((v, Some(Variant::Fields(fields)))) => {
                    let value = match fields.as_slice() {
                        [(f, s)] if f == "_0" => default(catalog, s, false),
                        _ if fields.iter().all(|(f, _)| f.starts_with('_')) => format!(
                            "[{}]",
                            fields
                                .iter()
                                .map(|(_, s)| default(catalog, s, false))
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                        _ => format!(
                            "{{{}}}",
                            fields
                                .iter()
                                .map(|(f, s)| format!("{f:?}: {}", default(catalog, s, false)))
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                    };
                    factory(format!("{{{v:?}: {value}}}"))
                }
                None => "None".into(),
            },
            None => "None".into(),
        },
        Shape::Unsupported(_) => "None".into(),
        _ => "0".into(),
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn every_type_has_a_python_class() {
        let src = super::module().expect("every type has a Python form");
        assert!(src.contains("class Header:"), "{src}");
        assert!(src.contains("\"robocog.Text\": Text,"), "{src}");
        for e in interfaces::msg::REGISTRY {
            assert!(src.contains(&format!("    {:?}: ", e.name)), "{}", e.name);
        }
    }

    #[test]
    fn the_committed_python_classes_are_what_the_types_give() {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../python/robocog/msg.py");
        let committed = std::fs::read_to_string(&path).expect("libs/python/robocog/msg.py");
        let generated = super::module().expect("every type has a Python form");
        assert!(
            committed.trim_end() == generated.trim_end(),
            "libs/python/robocog/msg.py is not what the message types give: write it again with \
             `robocog interface python > libs/python/robocog/msg.py`"
        );
    }
}
