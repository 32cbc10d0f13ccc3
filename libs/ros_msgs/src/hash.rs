//! RIHS01 type hashes (REP 2011, the ROS Interface Hashing Standard, version 1): what ROS 2
//! (and rmw_zenoh, in its key expressions and liveliness tokens) uses to tell whether two sides
//! mean the same type.
//!
//! The hash is the SHA-256 of a canonical JSON form of the type's description: the type's name
//! and fields, then the descriptions of every type it uses, sorted by name. Each field gives its
//! name and type (a `FieldType` id of `type_description_interfaces`, the array's capacity, the
//! string capacity and the nested type's name); constants and default values are not part of
//! it. The JSON is written as Python's `json.dumps` writes it (`", "` and `": "` separators, keys
//! in the order of the description), which is how `rosidl` computes it.

use crate::msgdef::{Array, Base, MsgDef, full_name};
use sha2::{Digest, Sha256};
use std::collections::{BTreeMap, BTreeSet};

/// `type_description_interfaces/msg/FieldType` ids of the primitives.
fn primitive_id(name: &str) -> u8 {
    match name {
        "int8" => 2,
        "uint8" => 3,
        "int16" => 4,
        "uint16" => 5,
        "int32" => 6,
        "uint32" => 7,
        "int64" => 8,
        "uint64" => 9,
        "float32" => 10,
        "float64" => 11,
        "char" => 13,
        "bool" => 15,
        "byte" => 16,
        "string" => 17,
        other => unreachable!("no primitive {other} in a robocog definition"),
    }
}

/// The `FieldType` of a field: the base id, moved into the range of its kind of array.
fn field_type_json(base: &Base, array: Array) -> String {
    const NESTED: u8 = 1;
    let (id, nested) = match base {
        Base::Primitive(p) => (primitive_id(p), String::new()),
        Base::Nested(n) => (NESTED, full_name(n)),
    };
    let (id, capacity) = match array {
        Array::Single => (id, 0),
        Array::Fixed(n) => (id + 48, n),
        Array::Unbounded => (id + 144, 0),
    };
    format!(
        "{{\"type_id\": {id}, \"capacity\": {capacity}, \"string_capacity\": 0, \"nested_type_name\": {}}}",
        json_string(&nested)
    )
}

fn json_string(s: &str) -> String {
    serde_json::Value::String(s.to_string()).to_string()
}

fn description_json(def: &MsgDef) -> String {
    let fields: Vec<String> = def
        .fields
        .iter()
        .map(|f| {
            format!(
                "{{\"name\": {}, \"type\": {}}}",
                json_string(&f.name),
                field_type_json(&f.base, f.array)
            )
        })
        .collect();
    format!(
        "{{\"type_name\": {}, \"fields\": [{}]}}",
        json_string(&full_name(&def.name)),
        fields.join(", ")
    )
}

/// The RIHS01 hash of message `root` (`RIHS01_` and 64 hex digits).
pub fn rihs01(messages: &BTreeMap<String, MsgDef>, root: &str) -> String {
    // Every message it uses, directly or not (sorted by full name, as the standard wants).
    let mut referenced = BTreeSet::new();
    let mut queue: Vec<&str> = messages[root].uses.iter().map(String::as_str).collect();
    while let Some(n) = queue.pop() {
        if referenced.insert((full_name(n), n.to_string())) {
            queue.extend(messages[n].uses.iter().map(String::as_str));
        }
    }
    let refs: Vec<String> = referenced
        .iter()
        .map(|(_, n)| description_json(&messages[n]))
        .collect();
    let json = format!(
        "{{\"type_description\": {}, \"referenced_type_descriptions\": [{}]}}",
        description_json(&messages[root]),
        refs.join(", ")
    );
    let digest = Sha256::digest(json.as_bytes());
    let hex: String = digest.iter().map(|b| format!("{b:02x}")).collect();
    format!("RIHS01_{hex}")
}
