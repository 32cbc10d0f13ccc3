//! Every message type of robocog, one module per area, and the registry that maps a type name to
//! its decoder so the `robocog topic` tools can print any payload as JSON.
//!
//! Rules for a message type (the CDR codec has no self-describing values):
//! - a `pub header: Header` field, `Default`, `Serialize`, `Deserialize`, `Clone`, `Debug`;
//! - no `Option`: use a flag or an empty `Vec`; no untagged or flattened enums;
//! - byte buffers as `#[serde(with = "serde_bytes")] Vec<u8>` so they encode as one block;
//! - units in field names or docs (`_m`, `_mm`, `_rad`, `_s`).
//!
//! Every type is listed once in the `messages!` invocation below, which gives it its type name and
//! puts it in [`REGISTRY`].

pub mod agent;
pub mod body;
pub mod command;
pub mod diag;
pub mod dr;
pub mod executive;
pub mod nao;
pub mod ros;
pub mod speech;
pub mod std_msgs;
pub mod tracking;
pub mod vision;

use crate::codec::{self, CodecError};
use crate::header::Header;
use serde::{Deserialize, Serialize, de::DeserializeOwned};

/// A message type of the bus.
pub trait Message: Serialize + DeserializeOwned + Default + Clone + Send + Sync + 'static {
    /// The type's name on the bus (`robocog.<Name>`), carried in liveliness tokens and in every
    /// sample's encoding.
    const TYPE_NAME: &'static str;
    fn header(&self) -> &Header;
    fn header_mut(&mut self) -> &mut Header;
}

/// A message that can be read in place. Its [`Borrowable::View`] is the same type on the wire, with
/// its big byte buffers borrowed (`&'a [u8]`) instead of owned: decoded from a received payload
/// with [`crate::codec::decode_borrowed`], the buffers point into the payload itself (the
/// publisher's shared memory, for a camera frame), and encoding a view gives exactly the bytes of
/// the owned message. See [`crate::bus::Subscriber::recv_borrowed`] and
/// [`crate::bus::Publisher::publish_view`].
pub trait Borrowable: Message {
    /// The message with its byte buffers borrowed.
    type View<'a>: Serialize + Deserialize<'a> + Default + std::fmt::Debug + Send + Sync;
    /// The view's header, to stamp it.
    fn view_header_mut<'v>(view: &'v mut Self::View<'_>) -> &'v mut Header;
}

/// What the generic tools know of a message type.
#[derive(Debug, Clone, Copy)]
pub struct TypeEntry {
    pub name: &'static str,
    /// CDR payload to JSON.
    pub to_json: fn(&[u8]) -> Result<serde_json::Value, RegistryError>,
    /// JSON to CDR payload; missing fields are an error (no guessing).
    pub from_json: fn(serde_json::Value) -> Result<Vec<u8>, RegistryError>,
    /// The JSON of a default value: what `robocog topic info` shows as the shape of the type.
    pub example: fn() -> serde_json::Value,
    /// A service's value reply of this type, as [`crate::raw::RawReply::Ok`] holds it (the
    /// reply's variant, then the value), to JSON.
    pub reply_to_json: fn(&[u8]) -> Result<serde_json::Value, RegistryError>,
}

#[derive(Debug, thiserror::Error)]
pub enum RegistryError {
    #[error("unknown message type {0:?} (not in this build's interfaces)")]
    UnknownType(String),
    #[error(transparent)]
    Codec(#[from] CodecError),
    #[error("JSON does not match {type_name}: {source}")]
    Json {
        type_name: &'static str,
        #[source]
        source: serde_json::Error,
    },
}

/// The entry for `name`, if this build knows the type.
pub fn lookup(name: &str) -> Result<&'static TypeEntry, RegistryError> {
    REGISTRY
        .iter()
        .find(|e| e.name == name)
        .ok_or_else(|| RegistryError::UnknownType(name.to_string()))
}

fn cdr_to_json<T: Message>(bytes: &[u8]) -> Result<serde_json::Value, RegistryError> {
    let v: T = codec::decode(bytes, T::TYPE_NAME)?;
    serde_json::to_value(&v).map_err(|source| RegistryError::Json {
        type_name: T::TYPE_NAME,
        source,
    })
}

fn json_to_cdr<T: Message>(json: serde_json::Value) -> Result<Vec<u8>, RegistryError> {
    let v: T = serde_json::from_value(json).map_err(|source| RegistryError::Json {
        type_name: T::TYPE_NAME,
        source,
    })?;
    Ok(codec::encode(&v, T::TYPE_NAME)?)
}

fn cdr_reply_to_json<T: Message>(wire: &[u8]) -> Result<serde_json::Value, RegistryError> {
    let v: T = match crate::raw::RawReply::Ok(wire.to_vec()).value() {
        Some(v) => v?,
        // (An `Ok` reply always has a value.)
        None => return Ok(serde_json::Value::Null),
    };
    serde_json::to_value(&v).map_err(|source| RegistryError::Json {
        type_name: T::TYPE_NAME,
        source,
    })
}

fn example_json<T: Message>() -> serde_json::Value {
    serde_json::to_value(T::default()).unwrap_or(serde_json::Value::Null)
}

/// Something done with every message type, as a type (for what needs the type itself rather than
/// the registry's functions, such as tracing its serde format to describe it to other tools).
pub trait TypeVisitor {
    fn visit<T: Message>(&mut self);
}

macro_rules! messages {
    ($($ty:ty => $name:literal),* $(,)?) => {
        $(
            impl Message for $ty {
                const TYPE_NAME: &'static str = $name;
                fn header(&self) -> &Header { &self.header }
                fn header_mut(&mut self) -> &mut Header { &mut self.header }
            }
        )*
        /// Every message type of this build.
        pub static REGISTRY: &[TypeEntry] = &[
            $(TypeEntry {
                name: $name,
                to_json: cdr_to_json::<$ty>,
                from_json: json_to_cdr::<$ty>,
                example: example_json::<$ty>,
                reply_to_json: cdr_reply_to_json::<$ty>,
            }),*
        ];

        /// Call `visitor` with every message type of this build, in the order of [`REGISTRY`].
        pub fn visit_types(visitor: &mut impl TypeVisitor) {
            $(visitor.visit::<$ty>();)*
        }
    };
}

messages! {
    std_msgs::Text => "robocog.Text",
    std_msgs::Ping => "robocog.Ping",
    std_msgs::Counter64 => "robocog.Counter64",
    std_msgs::ClockTime => "robocog.ClockTime",
    diag::Diagnostics => "robocog.Diagnostics",
    agent::AgentRequest => "robocog.agent.Request",
    agent::AgentReply => "robocog.agent.Reply",
    agent::AgentEvent => "robocog.agent.Event",
    vision::RgbdFrame => "robocog.RgbdFrame",
    vision::CameraStatus => "robocog.CameraStatus",
    tracking::BallTarget => "robocog.BallTarget",
    tracking::BallTrack => "robocog.BallTrack",
    tracking::BallEvent => "robocog.BallEvent",
    tracking::BallTruth => "robocog.sim.BallTruth",
    nao::NaoCommand => "robocog.nao.Command",
    nao::NaoLocalModel => "robocog.nao.LocalModel",
    nao::NaoWorldModel => "robocog.nao.WorldModel",
    nao::GameState => "robocog.nao.GameState",
    nao::NaoLinkEvent => "robocog.nao.LinkEvent",
    nao::FieldTruth => "robocog.sim.FieldTruth",
    nao::CoachRequest => "robocog.nao.CoachRequest",
    nao::CoachStatus => "robocog.nao.CoachStatus",
    dr::GetNodeRequest => "robocog.dr.GetNodeRequest",
    dr::NodeInfo => "robocog.dr.NodeInfo",
    dr::TransformRequest => "robocog.dr.TransformRequest",
    dr::TransformReply => "robocog.dr.TransformReply",
    dr::UpdateRequest => "robocog.dr.UpdateRequest",
    dr::UpdateReply => "robocog.dr.UpdateReply",
    dr::ProposeRequest => "robocog.dr.ProposeRequest",
    dr::ProposeReply => "robocog.dr.ProposeReply",
    dr::PredicateRequest => "robocog.dr.PredicateRequest",
    dr::PredicateReply => "robocog.dr.PredicateReply",
    dr::ForkRequest => "robocog.dr.ForkRequest",
    dr::ForkReply => "robocog.dr.ForkReply",
    dr::PddlRequest => "robocog.dr.PddlRequest",
    dr::PddlReply => "robocog.dr.PddlReply",
    dr::SnapshotRequest => "robocog.dr.SnapshotRequest",
    dr::SnapshotData => "robocog.dr.SnapshotData",
    dr::DrChange => "robocog.dr.DrChange",
    command::GameCommand => "robocog.GameCommand",
    command::Answer => "robocog.Answer",
    speech::AudioChunk => "robocog.AudioChunk",
    speech::Utterance => "robocog.speech.Utterance",
    speech::SayRequest => "robocog.speech.SayRequest",
    speech::SpeakingEvent => "robocog.speech.SpeakingEvent",
    speech::VoiceActivity => "robocog.speech.VoiceActivity",
    speech::TalkKey => "robocog.speech.TalkKey",
    speech::ListeningDirection => "robocog.speech.ListeningDirection",
    tracking::SimBall => "robocog.sim.Ball",
    body::JointGoal => "robocog.body.JointGoal",
    body::JointGoalReply => "robocog.body.JointGoalReply",
    body::JointStates => "robocog.body.JointStates",
    body::ReachGoal => "robocog.body.ReachGoal",
    body::ReachStatus => "robocog.body.ReachStatus",
    executive::StateTransition => "robocog.executive.StateTransition",
    executive::ConfigurationRequest => "robocog.executive.ConfigurationRequest",
    executive::Configuration => "robocog.executive.Configuration",
    executive::GameLog => "robocog.executive.GameLog",
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_registered_type_round_trips_through_cdr_and_json() {
        let mut names = std::collections::HashSet::new();
        for e in REGISTRY {
            assert!(names.insert(e.name), "{} registered twice", e.name);
            assert!(e.name.starts_with("robocog."), "{}", e.name);
            let json = (e.example)();
            let cdr = (e.from_json)(json.clone()).unwrap_or_else(|err| panic!("{}: {err}", e.name));
            let back = (e.to_json)(&cdr).unwrap_or_else(|err| panic!("{}: {err}", e.name));
            assert_eq!(back, json, "{}", e.name);
        }
    }

    #[test]
    fn unknown_types_and_bad_json_are_errors() {
        assert!(matches!(
            lookup("robocog.Nope"),
            Err(RegistryError::UnknownType(_))
        ));
        let text = lookup("robocog.Text").unwrap();
        assert!((text.from_json)(serde_json::json!({"text": 3})).is_err());
        assert!((text.to_json)(&[0, 1, 0, 0]).is_err());
    }
}
