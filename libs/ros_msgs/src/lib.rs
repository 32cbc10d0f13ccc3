//! ROS 2 interface definitions of robocog's messages, so that tools outside the project (ROS 2
//! decoders, Foxglove, `rosbags`, MCAP readers) can read robocog's payloads.
//!
//! **One source of truth: the Rust types.** Each type of the `interfaces` registry is walked
//! through its serde `Deserialize` impl as CDR sees it ([`probe`]), which gives its fields in
//! wire order, and a `.msg` definition is written from that ([`msgdef`]) for the `robocog_msgs`
//! package. Where the wire form is a ROS 2 standard message (`std_msgs/Header`,
//! `geometry_msgs/Point`, ...: `interfaces::msg::ros`), the definitions use it, and the tests
//! check that its definition is ROS 2's own. Since the payloads are CDR as ROS 2 writes it, a
//! ROS 2 decoder given these definitions reads our bytes as they are; the tests decode real
//! recordings with decoders from PyPI and check it.
//!
//! A type that no ROS 2 message could describe (an enum carrying data without a wire form, a
//! sequence of sequences) would have no definition: [`Definitions::ros_name`] says why, and
//! recordings would keep robocog's own schema for it. Every type of this build has one.

pub mod hash;
pub mod json;
pub mod msgdef;
pub mod probe;
pub mod python;

use interfaces::msg::{Message, TypeVisitor};
use msgdef::{MsgDef, PACKAGE, full_name, package_of, reference};
use probe::{Catalog, Shape};
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
    /// By robocog type name: its payload as a ROS 2 decoder reads it ([`json`]).
    views: BTreeMap<&'static str, RosView>,
}

type RosView = fn(&[u8]) -> Result<serde_json::Value, String>;

fn ros_view_of<T: Message>(payload: &[u8]) -> Result<serde_json::Value, String> {
    let value: T = interfaces::codec::decode(payload, T::TYPE_NAME).map_err(|e| e.to_string())?;
    json::to_value(&value).map_err(|e| e.to_string())
}

/// The definitions of this build, made once.
pub fn definitions() -> &'static Definitions {
    static DEFS: OnceLock<Definitions> = OnceLock::new();
    DEFS.get_or_init(Definitions::make)
}

/// The walk of every type of this build: the named types met, each type's root (its message's
/// name, or why it has none) and its ROS 2 view.
pub(crate) struct Collect {
    pub(crate) catalog: Catalog,
    pub(crate) roots: Vec<(&'static str, Result<String, String>)>,
    views: BTreeMap<&'static str, RosView>,
}

impl Collect {
    /// Walk every type of the registry.
    pub(crate) fn run() -> Collect {
        let mut collect = Collect {
            catalog: Catalog::default(),
            roots: Vec::new(),
            views: BTreeMap::new(),
        };
        interfaces::msg::visit_types(&mut collect);
        collect
    }
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
        self.views.insert(T::TYPE_NAME, ros_view_of::<T>);
    }
}

impl Definitions {
    fn make() -> Definitions {
        let collect = Collect::run();
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
            views: collect.views,
        }
    }

    /// Every robocog type name with its ROS 2 name (`robocog_msgs/msg/JointStates`) or why it
    /// has none.
    pub fn types(&self) -> impl Iterator<Item = (&'static str, Result<String, &str>)> + '_ {
        self.by_type.iter().map(|(ty, r)| {
            (
                *ty,
                r.as_ref().map(|n| full_name(n)).map_err(String::as_str),
            )
        })
    }

    /// The ROS 2 name of a robocog type (`robocog_msgs/msg/JointStates`), or why it has none.
    pub fn ros_name(&self, type_name: &str) -> Result<String, String> {
        match self.by_type.get(type_name) {
            Some(Ok(n)) => Ok(full_name(n)),
            Some(Err(why)) => Err(why.clone()),
            None => Err(format!(
                "{type_name} is not a message type of this build's interfaces"
            )),
        }
    }

    /// The robocog type whose ROS 2 name is `ros_name` (`robocog_msgs/msg/JointStates`).
    pub fn robocog_type(&self, ros_name: &str) -> Option<&'static str> {
        self.by_type
            .iter()
            .find(|(_, r)| r.as_deref().is_ok_and(|n| full_name(n) == ros_name))
            .map(|(ty, _)| *ty)
    }

    /// The full definition of a robocog type as rosbag2 and MCAP's `ros2msg` schemas hold it:
    /// its `.msg` text, then each message it uses (directly or not), once, after a line of `=`
    /// and `MSG: package/Name` (`robocog_msgs/Edge`, `std_msgs/Header`).
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
            out.push_str(&format!(
                "{SEPARATOR}\nMSG: {}\n{}",
                reference(&name),
                def.text
            ));
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

    /// The RIHS01 hash of one message, by its serde name (`std_msgs/msg/Header`, `Edge`).
    pub fn message_rihs01(&self, name: &str) -> Option<String> {
        self.messages
            .contains_key(name)
            .then(|| hash::rihs01(&self.messages, name))
    }

    /// The `.msg` text of one message, by its name in the package (`JointStates`) or its full
    /// name (`robocog_msgs/msg/JointStates`, `std_msgs/msg/Header`).
    pub fn message_text(&self, name: &str) -> Option<&str> {
        let name = name
            .strip_prefix(&format!("{PACKAGE}/msg/"))
            .unwrap_or(name);
        self.messages.get(name).map(|d| d.text.as_str())
    }

    /// The standard ROS 2 messages robocog's definitions use, by full name.
    pub fn standard_messages(&self) -> impl Iterator<Item = &str> + '_ {
        self.messages
            .keys()
            .filter(|n| package_of(n) != PACKAGE)
            .map(String::as_str)
    }

    /// A payload of robocog type `type_name` as a ROS 2 decoder reads it (see [`json`]).
    pub fn ros_json(&self, type_name: &str, payload: &[u8]) -> Result<serde_json::Value, String> {
        match self.views.get(type_name) {
            Some(view) => view(payload),
            None => Err(format!(
                "{type_name} is not a message type of this build's interfaces"
            )),
        }
    }

    /// Write the `robocog_msgs` package under `dir`: `robocog_msgs/msg/<Name>.msg` for every
    /// message of the package, with the `package.xml` and `CMakeLists.txt` of a ROS 2 interface
    /// package depending on the standard packages it uses, so `colcon build` can make it.
    /// Returns how many messages were written.
    pub fn export(&self, dir: &Path) -> std::io::Result<usize> {
        let pkg = dir.join(PACKAGE);
        std::fs::create_dir_all(pkg.join("msg"))?;
        let ours: Vec<&String> = self
            .messages
            .keys()
            .filter(|n| package_of(n) == PACKAGE)
            .collect();
        for name in &ours {
            std::fs::write(
                pkg.join("msg").join(format!("{name}.msg")),
                &self.messages[*name].text,
            )?;
        }
        let mut deps: Vec<&str> = self.standard_messages().map(package_of).collect();
        deps.dedup();
        let files: Vec<String> = ours.iter().map(|n| format!("  \"msg/{n}.msg\"")).collect();
        let find: String = deps
            .iter()
            .map(|d| format!("find_package({d} REQUIRED)\n"))
            .collect();
        let depend: String = deps
            .iter()
            .map(|d| format!("  <depend>{d}</depend>\n"))
            .collect();
        std::fs::write(
            pkg.join("CMakeLists.txt"),
            format!(
                "cmake_minimum_required(VERSION 3.8)\nproject({PACKAGE})\nfind_package(ament_cmake REQUIRED)\nfind_package(rosidl_default_generators REQUIRED)\n{find}rosidl_generate_interfaces(${{PROJECT_NAME}}\n{}\n  DEPENDENCIES {}\n)\nament_export_dependencies(rosidl_default_runtime)\nament_package()\n",
                files.join("\n"),
                deps.join(" ")
            ),
        )?;
        std::fs::write(
            pkg.join("package.xml"),
            format!(
                "<?xml version=\"1.0\"?>\n<package format=\"3\">\n  <name>{PACKAGE}</name>\n  <version>{}</version>\n  <description>The messages of robocog, written from its Rust types (robocog interface export).</description>\n  <maintainer email=\"robocog@example.invalid\">robocog</maintainer>\n  <license>Apache-2.0</license>\n  <buildtool_depend>ament_cmake</buildtool_depend>\n  <buildtool_depend>rosidl_default_generators</buildtool_depend>\n{depend}  <exec_depend>rosidl_default_runtime</exec_depend>\n  <member_of_group>rosidl_interface_packages</member_of_group>\n  <export><build_type>ament_cmake</build_type></export>\n</package>\n",
                env!("CARGO_PKG_VERSION")
            ),
        )?;
        Ok(ours.len())
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
        assert!(full.contains("std_msgs/Header header\n"), "{full}");
        assert_eq!(full.matches("MSG: std_msgs/Header\n").count(), 1, "{full}");
        assert_eq!(
            full.matches("MSG: builtin_interfaces/Time\n").count(),
            1,
            "{full}"
        );
        let header = d.message_text("std_msgs/msg/Header").unwrap();
        assert_eq!(header, "builtin_interfaces/Time stamp\nstring frame_id\n");
        assert_eq!(
            d.message_text("builtin_interfaces/msg/Time").unwrap(),
            "int32 sec\nuint32 nanosec\n"
        );
    }

    #[test]
    fn tagged_unions_are_messages_with_a_kind() {
        let d = definitions();
        for ty in [
            "robocog.dr.DrChange",
            "robocog.dr.ProposeRequest",
            "robocog.dr.SnapshotData",
        ] {
            d.ros_name(ty).unwrap_or_else(|why| panic!("{ty}: {why}"));
        }
        let text = d.message_text("ChangeEvent").unwrap();
        assert!(
            text.starts_with("uint32 CHANGE_EVENT_KIND_NODE_ADDED=0\n"),
            "{text}"
        );
        assert!(text.contains("\nrobocog_msgs/NodeSpec[] spec\n"), "{text}");
        let edge = d.message_text("Edge").unwrap();
        assert!(
            edge.contains("geometry_msgs/Transform transform\n"),
            "{edge}"
        );
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
        let payload = (interfaces::msg::lookup("robocog.BallTrack")
            .unwrap()
            .from_json)(json)
        .unwrap();
        let view = d.ros_json("robocog.BallTrack", &payload).unwrap();
        assert!(view["state"].is_u64(), "{view}");
        assert!(view["header"]["stamp"]["sec"].is_i64(), "{view}");
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
