//! Every topic and service of robocog, as typed constants.

use crate::msg::{diag::Diagnostics, std_msgs};
use crate::topic::{Service, Topic};

/// Each component's counters (decode failures, drops by reason), about once a second.
pub const DIAGNOSTICS: Topic<Diagnostics> = Topic::new("diagnostics");

/// A replay's time: components started with `--clock bus` follow it (see [`crate::clock`]).
pub const CLOCK: Topic<std_msgs::ClockTime> = Topic::new("clock");

/// Free text, for fixtures and demos.
pub const CHATTER: Topic<std_msgs::Text> = Topic::new("chatter");
/// An echo service (fixtures, health checks): replies with the request's text.
pub const ECHO: Service<std_msgs::Text, std_msgs::Text> = Service::new("echo");

// The agents of a graph over several machines (`robocog agent`).
/// What the components an agent runs write and when they exit, for the launcher.
pub const AGENT_EVENTS: Topic<crate::msg::agent::AgentEvent> = Topic::new("agent/events");
/// The control service of one machine's agent (`agent/<machine>/control`): start, stop, status.
/// `None` when `machine` is not a lowercase name (`[a-z0-9_-]`). The name lives as long as the
/// process (one per machine of the graph).
pub fn agent_control(
    machine: &str,
) -> Option<Service<crate::msg::agent::AgentRequest, crate::msg::agent::AgentReply>> {
    if !is_valid_machine(machine) {
        return None;
    }
    let name: &'static str = Box::leak(format!("agent/{machine}/control").into_boxed_str());
    Some(Service::new(name))
}

/// Whether `machine` can name a machine of a graph: lowercase letters, digits, `_`, `-`.
pub fn is_valid_machine(machine: &str) -> bool {
    !machine.contains('/') && crate::topic::is_valid_name(machine)
}

/// The bus benchmark's probes.
pub const BENCH_PING: Topic<std_msgs::Ping> = Topic::new("bench/ping");
pub const BENCH_PONG: Topic<std_msgs::Ping> = Topic::new("bench/pong");
pub const BENCH_COUNT: Topic<std_msgs::Counter64> = Topic::new("bench/count");
/// What the receiving end of the throughput probe counted: `sent_ns` = ns from the first to the
/// last message, `data` = the count (u64, little endian).
pub const BENCH_COUNT_REPORT: Topic<std_msgs::Ping> = Topic::new("bench/count_report");
pub const BENCH_FRAME: Topic<crate::msg::vision::RgbdFrame> = Topic::new("bench/frame");
pub const BENCH_FRAME_BACK: Topic<crate::msg::vision::RgbdFrame> = Topic::new("bench/frame_back");

// deep_representation
/// The world model's change events, in order (every accepted change of the live graph).
pub const DR_CHANGES: Topic<crate::msg::dr::DrChange> = Topic::new("dr/changes");
/// One node of the world model by name.
pub const DR_GET_NODE: Service<crate::msg::dr::GetNodeRequest, crate::msg::dr::NodeInfo> =
    Service::new("dr/get_node");
/// `target_T_source`, now or at a past time.
pub const DR_TRANSFORM: Service<crate::msg::dr::TransformRequest, crate::msg::dr::TransformReply> =
    Service::new("dr/transform");
/// Perception and odometry updates (attributes, free poses, joint values), applied straight in.
pub const DR_UPDATE: Service<crate::msg::dr::UpdateRequest, crate::msg::dr::UpdateReply> =
    Service::new("dr/update");
/// A structural change, accepted or rejected with the reason.
pub const DR_PROPOSE: Service<crate::msg::dr::ProposeRequest, crate::msg::dr::ProposeReply> =
    Service::new("dr/propose");
/// Whether a predicate holds (or every fact that holds).
pub const DR_PREDICATE: Service<crate::msg::dr::PredicateRequest, crate::msg::dr::PredicateReply> =
    Service::new("dr/predicate");
/// Virtual actions on a private copy; the predicate changes and the differences.
pub const DR_FORK: Service<crate::msg::dr::ForkRequest, crate::msg::dr::ForkReply> =
    Service::new("dr/fork");
/// The state as a PDDL problem.
pub const DR_PDDL: Service<crate::msg::dr::PddlRequest, crate::msg::dr::PddlReply> =
    Service::new("dr/pddl");
/// The current state as a snapshot (every node's description, the body parts; no history).
pub const DR_SNAPSHOT: Service<crate::msg::dr::SnapshotRequest, crate::msg::dr::SnapshotData> =
    Service::new("dr/snapshot");
/// Replace the state with a snapshot (replies with the new state's snapshot).
pub const DR_RESTORE: Service<crate::msg::dr::SnapshotData, crate::msg::dr::SnapshotData> =
    Service::new("dr/restore");

// nao (the coach game's link to the robot)
/// Operator commands for the controlled robot (panel, voice, executive).
pub const NAO_COMMAND: Topic<crate::msg::nao::NaoCommand> = Topic::new("nao/command");
/// Each robot's local world model, as its debug packets arrive (10 Hz per robot).
pub const NAO_LOCAL_MODEL: Topic<crate::msg::nao::NaoLocalModel> = Topic::new("nao/local_model");
/// The fused team world model.
pub const NAO_WORLD_MODEL: Topic<crate::msg::nao::NaoWorldModel> = Topic::new("nao/world_model");
/// The GameController's state, our team first.
pub const NAO_GAME_STATE: Topic<crate::msg::nao::GameState> = Topic::new("nao/game_state");
/// Link established / robot not responding / restored.
pub const NAO_LINK: Topic<crate::msg::nao::NaoLinkEvent> = Topic::new("nao/link");
/// Coach requests for the controlled robot (the panel), answered and checked by the Executive's
/// coach machine before they become `nao/command`.
pub const COACH_REQUEST: Topic<crate::msg::nao::CoachRequest> = Topic::new("coach/request");
/// The coach machine's memory (last and pending command, last-seen times), for the panel.
pub const COACH_STATUS: Topic<crate::msg::nao::CoachStatus> = Topic::new("coach/status");
/// Ground truth of the simulated SPL field.
pub const SIM_FIELD_TRUTH: Topic<crate::msg::nao::FieldTruth> = Topic::new("sim/field_truth");

// voice
/// Microphone audio in (16 kHz mono s16le for the recognizer; other formats are dropped, counted).
pub const AUDIO_IN: Topic<crate::msg::speech::AudioChunk> = Topic::new("audio/in");
/// How much of `audio/in` its publishers keep ([`crate::Bus::recent_publisher`]) for a recognizer
/// that restarts: the words said while it was down are heard when it is back.
pub const AUDIO_IN_KEPT: std::time::Duration = std::time::Duration::from_secs(8);
/// Synthesized speech out, as the speech generator plays it.
pub const AUDIO_OUT: Topic<crate::msg::speech::AudioChunk> = Topic::new("audio/out");
/// Every utterance the recognizer decoded, with its confidence and command.
pub const SPEECH_UTTERANCE: Topic<crate::msg::speech::Utterance> = Topic::new("speech/utterance");
/// The recognizer's end-pointer: someone started or stopped speaking (before decoding).
pub const SPEECH_ACTIVITY: Topic<crate::msg::speech::VoiceActivity> = Topic::new("speech/activity");
/// Where a recognizer hearing through a microphone array listens, and where it hears sound from.
pub const SPEECH_LISTENING: Topic<crate::msg::speech::ListeningDirection> =
    Topic::new("speech/listening");
/// The operator's talk key, for a recognizer in push-to-talk mode (the command panel's button).
pub const SPEECH_TALK: Topic<crate::msg::speech::TalkKey> = Topic::new("speech/talk");
/// Requests to say something, with a priority (urgent interrupts).
pub const SPEECH_SAY: Topic<crate::msg::speech::SayRequest> = Topic::new("speech/say");
/// The speech generator's progress: queued, started, finished, interrupted.
pub const SPEECH_SPEAKING: Topic<crate::msg::speech::SpeakingEvent> = Topic::new("speech/speaking");
/// Validated game commands (voice after the dialog, or the command panel).
pub const GAME_COMMAND: Topic<crate::msg::command::GameCommand> = Topic::new("game/command");
/// Yes/no answers to the dialog's "Did you say ...?" from the command panel.
pub const GAME_ANSWER: Topic<crate::msg::command::Answer> = Topic::new("game/answer");

// vision
/// Registered RGB-D frames of the head camera (the `rgbd` component), about 1.5 MB each at
/// 640x480: shared memory on one host.
pub const VISION_RGBD: Topic<crate::msg::vision::RgbdFrame> = Topic::new("vision/rgbd");
/// The head camera's health (the `rgbd` component's hardware drivers): streaming or not, and why.
pub const VISION_CAMERA_STATUS: Topic<crate::msg::vision::CameraStatus> =
    Topic::new("vision/camera_status");
/// What the ball tracker looks for (colour, size); `active = false` clears it.
pub const VISION_BALL_TARGET: Topic<crate::msg::tracking::BallTarget> =
    Topic::new("vision/ball_target");
/// The ball tracker's result, one per processed frame (camera optical frame).
pub const VISION_BALL: Topic<crate::msg::tracking::BallTrack> = Topic::new("vision/ball");
/// Ball detected / out of view / lost / detection timed out.
pub const VISION_BALL_EVENTS: Topic<crate::msg::tracking::BallEvent> =
    Topic::new("vision/ball_events");
/// Ground truth of the simulated ball (the `rgbd` sim driver), one per simulated frame.
pub const SIM_BALL_TRUTH: Topic<crate::msg::tracking::BallTruth> = Topic::new("sim/ball_truth");
/// The simulated world's ball (the simulated person holds, moves and puts it away).
pub const SIM_BALL: Topic<crate::msg::tracking::SimBall> = Topic::new("sim/ball");

// body
/// Every joint's measured state, 100 Hz or more (`joint_motor`).
pub const BODY_JOINT_STATES: Topic<crate::msg::body::JointStates> = Topic::new("body/joint_states");
/// A joint goal (or release), accepted or refused with the joint and limit named.
pub const BODY_JOINT_GOAL: Service<crate::msg::body::JointGoal, crate::msg::body::JointGoalReply> =
    Service::new("body/joint_goal");
/// Reach and gaze goals for `body_inverse_kinematics` (replace per body part; cancel).
pub const BODY_REACH: Topic<crate::msg::body::ReachGoal> = Topic::new("body/reach");
/// Moving / reached / unreachable / cancelled / failed, per reach goal.
pub const BODY_REACH_STATUS: Topic<crate::msg::body::ReachStatus> = Topic::new("body/reach_status");

// executive
/// Every step of the Executive's machines.
pub const EXECUTIVE_TRANSITIONS: Topic<crate::msg::executive::StateTransition> =
    Topic::new("executive/transitions");
/// The current configuration of a machine (and its diagram).
pub const EXECUTIVE_CONFIGURATION: Service<
    crate::msg::executive::ConfigurationRequest,
    crate::msg::executive::Configuration,
> = Service::new("executive/configuration");
/// The readable game log.
pub const EXECUTIVE_LOG: Topic<crate::msg::executive::GameLog> = Topic::new("executive/log");
/// A structural change of the DR checked against the game first (seed 001 §V: structural changes
/// pass through the Executive); accepted ones are forwarded to `dr/propose` and its reply returned.
pub const EXECUTIVE_PROPOSE: Service<crate::msg::dr::ProposeRequest, crate::msg::dr::ProposeReply> =
    Service::new("executive/propose");
