//! ROS 2 interface definitions of robocog's messages, so that tools outside the project (ROS 2
//! decoders, Foxglove, `rosbags`, MCAP readers) can read robocog's payloads.
//!
//! **One source of truth: the Rust types.** Each type of the `interfaces` registry is walked
//! through its serde `Deserialize` impl ([`probe`]), which gives its fields in wire order, and a
//! `.msg` definition is written from that ([`msgdef`]) for the `robocog_msgs` package. Since the
//! payloads are CDR as ROS 2 writes it, a ROS 2 decoder given these definitions reads our bytes
//! as they are; the tests decode real recordings with decoders from PyPI and check it.
//!
//! Types that no ROS 2 message can describe (an enum carrying data is a tagged union) have no
//! definition: [`Definitions::ros_name`] says why, and recordings keep robocog's own schema for
//! them.

pub mod hash;
pub mod msgdef;
pub mod probe;

use interfaces::msg::{Message, TypeVisitor};
use msgdef::{MsgDef, PACKAGE};
use probe::{Catalog, Container, Shape};
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::OnceLock;

/// The separator between the definitions of a full definition (rosbag2's convention).
const SEPARATOR: &str =
    "================================================================================";

/// The ROS 2 definitions of every message type of this build.
#[derive(Debug)]
pub struct Definitions {
    /// By robocog type name (`robocog.body.JointStates`): its message's name, or why it has none.
    by_type: BTreeMap<&'static str, Result<String, String>>,
    /// Every message that has a definition, by name.
    messages: BTreeMap<String, MsgDef>,
    catalog: Catalog,
}

/// The definitions of this build, made once.
pub fn definitions() -> &'static Definitions {
    static DEFS: OnceLock<Definitions> = OnceLock::new();
    DEFS.get_or_init(Definitions::make)
}

struct Collect {
    catalog: Catalog,
    roots: Vec<(&'static str, Result<String, String>)>,
}

impl TypeVisitor for Collect {
    fn visit<T: Message>(&mut self) {
        // On a copy: a type that cannot be described leaves nothing half-described behind.
        let mut catalog = self.catalog.clone();
        let root = match probe::describe::<T>(&mut catalog) {
            Ok(Shape::Named(name)) => {
                self.catalog = catalog;
                Ok(name)
            }
            Ok(other) => Err(format!("it is not a struct ({other:?})")),
            Err(e) => Err(e.to_string()),
        };
        self.roots.push((T::TYPE_NAME, root));
    }
}

impl Definitions {
    fn make() -> Definitions {
        let mut collect = Collect {
            catalog: Catalog::default(),
            roots: Vec::new(),
        };
        interfaces::msg::visit_types(&mut collect);
        let mut writer = msgdef::Writer::new(&collect.catalog);
        let by_type = collect
            .roots
            .into_iter()
            .map(|(ty, root)| {
                let named = root.and_then(|name| writer.message(&name).map(|d| d.name));
                (ty, named)
            })
            .collect();
        let messages = writer
            .into_done()
            .into_iter()
            .filter_map(|(name, d)| d.ok().map(|d| (name, d)))
            .collect();
        Definitions {
            by_type,
            messages,
            catalog: collect.catalog,
        }
    }

    /// Every robocog type name with its ROS 2 name (`robocog_msgs/msg/JointStates`) or why it
    /// has none.
    pub fn types(&self) -> impl Iterator<Item = (&'static str, Result<String, &str>)> + '_ {
        self.by_type.iter().map(|(ty, r)| {
            (
                *ty,
                r.as_ref()
                    .map(|n| format!("{PACKAGE}/msg/{n}"))
                    .map_err(String::as_str),
            )
        })
    }

    /// The ROS 2 name of a robocog type (`robocog_msgs/msg/JointStates`), or why it has none.
    pub fn ros_name(&self, type_name: &str) -> Result<String, String> {
        match self.by_type.get(type_name) {
            Some(Ok(n)) => Ok(format!("{PACKAGE}/msg/{n}")),
            Some(Err(why)) => Err(why.clone()),
            None => Err(format!(
                "{type_name} is not a message type of this build's interfaces"
            )),
        }
    }

    /// The robocog type whose ROS 2 name is `ros_name` (`robocog_msgs/msg/JointStates`).
    pub fn robocog_type(&self, ros_name: &str) -> Option<&'static str> {
        let name = ros_name.strip_prefix(PACKAGE)?.strip_prefix("/msg/")?;
        self.by_type
            .iter()
            .find(|(_, r)| r.as_deref() == Ok(name))
            .map(|(ty, _)| *ty)
    }

    /// The full definition of a robocog type as rosbag2 and MCAP's `ros2msg` schemas hold it:
    /// its `.msg` text, then each message it uses (directly or not), once, after a line of `=`
    /// and `MSG: robocog_msgs/Name`.
    pub fn full_definition(&self, type_name: &str) -> Result<String, String> {
        let Some(Ok(root)) = self.by_type.get(type_name) else {
            return Err(self.ros_name(type_name).err().unwrap_or_default());
        };
        let mut out = self.messages[root].text.clone();
        let mut seen = vec![root.clone()];
        let mut queue: Vec<String> = self.messages[root].uses.clone();
        while !queue.is_empty() {
            let name = queue.remove(0);
            if seen.contains(&name) {
                continue;
            }
            let def = &self.messages[&name];
            out.push_str(&format!("{SEPARATOR}\nMSG: {PACKAGE}/{name}\n{}", def.text));
            queue.extend(def.uses.iter().cloned());
            seen.push(name);
        }
        Ok(out)
    }

    /// The RIHS01 type hash (REP 2011) of a robocog type, or why it has no definition.
    pub fn rihs01(&self, type_name: &str) -> Result<String, String> {
        match self.by_type.get(type_name) {
            Some(Ok(root)) => Ok(hash::rihs01(&self.messages, root)),
            _ => Err(self.ros_name(type_name).err().unwrap_or_default()),
        }
    }

    /// The `.msg` text of one message of the package, by its name (`JointStates`).
    pub fn message_text(&self, name: &str) -> Option<&str> {
        self.messages.get(name).map(|d| d.text.as_str())
    }

    /// Write the `robocog_msgs` package under `dir`: `robocog_msgs/msg/<Name>.msg` for every
    /// message, with the `package.xml` and `CMakeLists.txt` of a ROS 2 interface package, so
    /// `colcon build` can make it. Returns how many messages were written.
    pub fn export(&self, dir: &Path) -> std::io::Result<usize> {
        let pkg = dir.join(PACKAGE);
        std::fs::create_dir_all(pkg.join("msg"))?;
        for (name, def) in &self.messages {
            std::fs::write(pkg.join("msg").join(format!("{name}.msg")), &def.text)?;
        }
        let files: Vec<String> = self
            .messages
            .keys()
            .map(|n| format!("  \"msg/{n}.msg\""))
            .collect();
        std::fs::write(
            pkg.join("CMakeLists.txt"),
            format!(
                "cmake_minimum_required(VERSION 3.8)\nproject({PACKAGE})\nfind_package(ament_cmake REQUIRED)\nfind_package(rosidl_default_generators REQUIRED)\nrosidl_generate_interfaces(${{PROJECT_NAME}}\n{}\n)\nament_export_dependencies(rosidl_default_runtime)\nament_package()\n",
                files.join("\n")
            ),
        )?;
        std::fs::write(
            pkg.join("package.xml"),
            format!(
                "<?xml version=\"1.0\"?>\n<package format=\"3\">\n  <name>{PACKAGE}</name>\n  <version>{}</version>\n  <description>The messages of robocog, written from its Rust types (robocog interface export).</description>\n  <maintainer email=\"robocog@example.invalid\">robocog</maintainer>\n  <license>Apache-2.0</license>\n  <buildtool_depend>ament_cmake</buildtool_depend>\n  <buildtool_depend>rosidl_default_generators</buildtool_depend>\n  <exec_depend>rosidl_default_runtime</exec_depend>\n  <member_of_group>rosidl_interface_packages</member_of_group>\n  <export><build_type>ament_cmake</build_type></export>\n</package>\n",
                env!("CARGO_PKG_VERSION")
            ),
        )?;
        Ok(self.messages.len())
    }

    /// A message's JSON (as `robocog topic echo` prints it) as a ROS 2 decoder reads the same
    /// payload: enum variants become their integer values, the rest is unchanged.
    pub fn ros_view(&self, type_name: &str, json: &serde_json::Value) -> serde_json::Value {
        match self.by_type.get(type_name) {
            Some(Ok(root)) => self.view(&Shape::Named(root.clone()), json),
            _ => json.clone(),
        }
    }

    fn view(&self, shape: &Shape, v: &serde_json::Value) -> serde_json::Value {
        use serde_json::Value;
        match (shape, v) {
            (Shape::Seq(inner) | Shape::Array(inner, _), Value::Array(items)) => {
                Value::Array(items.iter().map(|i| self.view(inner, i)).collect())
            }
            (Shape::Named(n), _) => match (self.catalog.types.get(n), v) {
                (Some(Container::Struct(fields)), Value::Object(map)) => Value::Object(
                    fields
                        .iter()
                        .map(|(f, s)| {
                            let fv = map.get(f).cloned().unwrap_or(Value::Null);
                            (f.clone(), self.view(s, &fv))
                        })
                        .collect(),
                ),
                (Some(Container::Newtype(inner)), _) => self.view(inner, v),
                (Some(Container::Enum(variants)), Value::String(s)) => variants
                    .iter()
                    .position(|(name, _)| name == s)
                    .map(|i| Value::from(i as u64))
                    .unwrap_or_else(|| v.clone()),
                _ => v.clone(),
            },
            _ => v.clone(),
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn every_type_is_described_and_the_refusals_say_why() {
        let d = definitions();
        let all: Vec<_> = d.types().collect();
        assert_eq!(all.len(), interfaces::msg::REGISTRY.len());
        for (ty, r) in &all {
            match r {
                Ok(name) => {
                    assert!(name.starts_with("robocog_msgs/msg/"), "{ty}: {name}");
                    let full = d.full_definition(ty).unwrap();
                    assert!(!full.is_empty(), "{ty}");
                }
                Err(why) => {
                    assert!(!why.is_empty(), "{ty}");
                    assert!(d.full_definition(ty).is_err());
                }
            }
        }
        // The common ones map.
        for ty in [
            "robocog.body.JointStates",
            "robocog.BallTrack",
            "robocog.RgbdFrame",
            "robocog.speech.Utterance",
            "robocog.AudioChunk",
        ] {
            d.ros_name(ty).unwrap_or_else(|why| panic!("{ty}: {why}"));
        }
    }

    #[test]
    fn a_definition_lists_its_dependencies_once_after_itself() {
        let d = definitions();
        let full = d.full_definition("robocog.body.JointStates").unwrap();
        assert!(full.contains("robocog_msgs/Header header\n"), "{full}");
        assert_eq!(
            full.matches("MSG: robocog_msgs/Header\n").count(),
            1,
            "{full}"
        );
        let header = d.message_text("Header").unwrap();
        assert_eq!(header, "int64 stamp_ns\nuint64 seq\nstring frame_id\n");
    }

    #[test]
    fn unit_enums_are_integers_with_constants_and_the_json_follows() {
        let d = definitions();
        let name = d.ros_name("robocog.BallTrack").unwrap();
        let text = d
            .message_text(name.rsplit('/').next().unwrap())
            .unwrap()
            .to_string();
        assert!(text.contains("uint32 BALL_TRACK_STATE_"), "{text}");
        let json = (interfaces::msg::lookup("robocog.BallTrack")
            .unwrap()
            .example)();
        let view = d.ros_view("robocog.BallTrack", &json);
        assert!(view["state"].is_u64(), "{view}");
    }

    #[test]
    fn unknown_types_are_refused() {
        let d = definitions();
        assert!(
            d.ros_name("robocog.Nope")
                .unwrap_err()
                .contains("not a message type")
        );
    }
}
