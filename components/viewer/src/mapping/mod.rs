//! Topic → rerun archetype: [`Mapper::map`] turns one sample into the entities to log.
//!
//! The mapping is a plain function of the sample and of what the mapper remembers (the robot
//! model, the ball's trajectory, which static geometry was drawn, per-topic rates): no bus, no
//! viewer. See the crate doc for the entity table, frames and units.

use interfaces::Header;
use interfaces::codec::{self, CodecError};
use interfaces::msg::{self, Message};
use interfaces::msg::{
    body, command, diag, dr, executive, nao, speech, std_msgs, tracking, vision,
};
use nalgebra::Isometry3;
use rerun::AsComponents;
use robot_model::{RobotModel, Shape};
use std::collections::{BTreeMap, HashMap, VecDeque};
use world_model::field::FieldModel;
use world_model::graph::{At, SceneGraph};
use world_model::types::TransformIso;

mod coach_field;
mod dr_mirror;
mod robot;

/// One thing to log: an archetype at an entity path.
pub struct Logged {
    /// The entity path (`world/robot/base_footprint/...`).
    pub path: String,
    /// Static data (geometry that never changes) is logged once, outside the timelines.
    pub is_static: bool,
    pub data: Box<dyn AsComponents + Send>,
}

impl std::fmt::Debug for Logged {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Logged")
            .field("path", &self.path)
            .field("is_static", &self.is_static)
            .field("archetypes", &self.archetypes())
            .finish()
    }
}

impl Logged {
    fn new(path: impl Into<String>, data: impl AsComponents + Send + 'static) -> Self {
        Self {
            path: path.into(),
            is_static: false,
            data: Box::new(data),
        }
    }
    fn fixed(path: impl Into<String>, data: impl AsComponents + Send + 'static) -> Self {
        Self {
            is_static: true,
            ..Self::new(path, data)
        }
    }
    /// The archetype names of the data (`rerun.archetypes.Points3D`), for tests and logs.
    pub fn archetypes(&self) -> Vec<String> {
        let mut v: Vec<String> = self
            .data
            .as_serialized_batches()
            .iter()
            .filter_map(|b| b.descriptor.archetype.map(|a| a.to_string()))
            .collect();
        v.sort();
        v.dedup();
        v
    }
}

/// What one sample becomes.
#[derive(Debug, Default)]
pub struct Mapped {
    /// The header stamp of the sample (ns since the epoch), 0 when it had none.
    pub stamp_ns: i64,
    pub items: Vec<Logged>,
}

/// Why a sample was skipped.
#[derive(Debug, thiserror::Error)]
pub enum MapError {
    #[error("topic {topic}: message type {type_name:?} is not in this build's interfaces")]
    UnknownType { topic: String, type_name: String },
    #[error("topic {topic}: {source}")]
    Undecodable {
        topic: String,
        #[source]
        source: CodecError,
    },
    #[error("topic {topic}: {reason}")]
    Invalid { topic: String, reason: String },
}

/// How the mapper thins heavy streams.
#[derive(Debug, Clone, Copy)]
pub struct MapperOptions {
    /// At most this many camera frames per second per topic go to rerun (the others are thinned,
    /// counted in the topic's `thinned` scalar); 0 = every frame.
    pub image_hz: f64,
    /// Points kept in the ball's trajectory.
    pub trajectory_len: usize,
}

impl Default for MapperOptions {
    fn default() -> Self {
        Self {
            image_hz: 10.0,
            trajectory_len: 300,
        }
    }
}

/// One topic's figures over the last period.
#[derive(Debug, Clone, PartialEq)]
pub struct TopicFigures {
    pub topic: String,
    /// Samples per second received.
    pub rate_hz: f64,
    /// Mean delay from the header stamp to the receipt (ms), when stamped samples came.
    pub latency_ms: Option<f64>,
    /// Camera frames not logged so far (thinned to the image rate).
    pub thinned: u64,
}

#[derive(Debug, Default)]
struct TopicStats {
    received: u64,
    in_window: u64,
    latency_sum_s: f64,
    latency_n: u64,
    thinned: u64,
    last_image_ns: i64,
}

/// Remembers what the mapping needs across samples. See the module doc.
pub struct Mapper {
    options: MapperOptions,
    robot: Option<RobotModel>,
    /// Entity path of each link of `robot`, by link index.
    link_paths: Vec<String>,
    robot_drawn: bool,
    field: Option<FieldModel>,
    field_drawn: bool,
    pinholes: HashMap<String, (u32, u32, [f64; 4])>,
    trajectories: HashMap<String, VecDeque<[f32; 3]>>,
    stats: BTreeMap<String, TopicStats>,
    last_stats_ns: i64,
    last_text: HashMap<String, String>,
    dr: DrMirror,
}

/// The viewer's copy of the deep representation: restored from a `dr/snapshot` reply, kept up to
/// date by replaying `dr/changes` through the library (`SceneGraph::apply`), drawn at most every
/// [`DR_DRAW_EVERY_NS`] (the DR follows the joint states at 100 Hz).
#[derive(Default)]
struct DrMirror {
    graph: Option<SceneGraph>,
    /// Sequence number of the last change applied.
    last_seq: u64,
    /// Changes arrived that the mirror could not apply (no snapshot yet, a gap, a rejected event).
    wants_snapshot: bool,
    dirty: bool,
    last_draw_ns: i64,
    /// Each node's `world_T_node` as last drawn (translation, quaternion), to redraw only the
    /// nodes that moved and to clear the removed ones.
    drawn: HashMap<String, [f32; 7]>,
}

/// The DR's nodes are redrawn at most this often (ns).
pub const DR_DRAW_EVERY_NS: i64 = 100_000_000;

impl std::fmt::Debug for Mapper {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Mapper")
            .field("robot", &self.robot.as_ref().map(|r| r.name.clone()))
            .field("field", &self.field.is_some())
            .field("topics", &self.stats.len())
            .finish()
    }
}

/// The root of the robot's link tree.
pub const ROBOT_ROOT: &str = "world/robot";

fn tr(iso: &Isometry3<f64>) -> rerun::Transform3D {
    let t = iso.translation.vector;
    let q = iso.rotation.coords; // x, y, z, w
    rerun::Transform3D::from_translation_rotation(
        [t.x as f32, t.y as f32, t.z as f32],
        rerun::Quaternion::from_xyzw([q.x as f32, q.y as f32, q.z as f32, q.w as f32]),
    )
}

fn v3(p: [f64; 3]) -> [f32; 3] {
    [p[0] as f32, p[1] as f32, p[2] as f32]
}

fn text(s: impl Into<String>) -> rerun::TextLog {
    rerun::TextLog::new(s.into()).with_level(rerun::TextLogLevel::INFO)
}

fn warn(s: impl Into<String>) -> rerun::TextLog {
    rerun::TextLog::new(s.into()).with_level(rerun::TextLogLevel::WARN)
}

const GREEN: rerun::Color = rerun::Color(rerun::Rgba32::from_rgb(40, 200, 60));
const RED: rerun::Color = rerun::Color(rerun::Rgba32::from_rgb(230, 40, 40));
const YELLOW: rerun::Color = rerun::Color(rerun::Rgba32::from_rgb(240, 200, 40));
const GREY: rerun::Color = rerun::Color(rerun::Rgba32::from_rgb(150, 150, 150));
const BLUE: rerun::Color = rerun::Color(rerun::Rgba32::from_rgb(60, 120, 240));
const ORANGE: rerun::Color = rerun::Color(rerun::Rgba32::from_rgb(255, 140, 0));
const WHITE: rerun::Color = rerun::Color(rerun::Rgba32::from_rgb(240, 240, 240));

/// Only the header of any message (every message starts with it).
#[derive(serde::Deserialize)]
struct HeaderOnly {
    header: Header,
}

fn decode<T: Message>(topic: &str, payload: &[u8]) -> Result<T, MapError> {
    codec::decode::<T>(payload, T::TYPE_NAME).map_err(|source| MapError::Undecodable {
        topic: topic.to_string(),
        source,
    })
}

impl Mapper {
    /// A mapper drawing `robot` (the URDF) for joint states and camera frames, and `field` for
    /// the Nao game; either may be absent (that part is then not drawn).
    pub fn new(
        robot: Option<RobotModel>,
        field: Option<FieldModel>,
        options: MapperOptions,
    ) -> Self {
        let link_paths = robot.as_ref().map(link_paths).unwrap_or_default();
        Self {
            options,
            robot,
            link_paths,
            robot_drawn: false,
            field,
            field_drawn: false,
            pinholes: HashMap::new(),
            trajectories: HashMap::new(),
            stats: BTreeMap::new(),
            last_stats_ns: 0,
            last_text: HashMap::new(),
            dr: DrMirror {
                wants_snapshot: true,
                ..DrMirror::default()
            },
        }
    }

    /// The entity path of a frame: its link in the robot tree, else `world/frames/<frame>`.
    pub fn frame_path(&self, frame: &str) -> String {
        if let Some(r) = &self.robot
            && let Ok(i) = r.link_index(frame)
            && let Some(p) = self.link_paths.get(i)
        {
            return p.clone();
        }
        let f = if frame.is_empty() { "unknown" } else { frame };
        format!("world/frames/{f}")
    }

    /// The entity the head camera's image is logged under (`<optical frame link>/camera`).
    pub fn camera_path(&self, frame: &str) -> String {
        format!("{}/camera", self.frame_path(frame))
    }

    /// The camera entity of the robot model's first camera (`<link>/camera`).
    pub fn head_camera_path(&self) -> String {
        let frame = self
            .robot
            .as_ref()
            .and_then(|r| r.cameras.first())
            .map(|c| c.frame.clone())
            .unwrap_or_else(|| "camera".into());
        self.camera_path(&frame)
    }

    /// Map one sample of `topic`, whose encoding names `type_name`, received at `receipt_ns`.
    pub fn map(
        &mut self,
        topic: &str,
        type_name: &str,
        payload: &[u8],
        receipt_ns: i64,
    ) -> Result<Mapped, MapError> {
        if msg::lookup(type_name).is_err() {
            return Err(MapError::UnknownType {
                topic: topic.to_string(),
                type_name: type_name.to_string(),
            });
        }
        let header: HeaderOnly = decode_header(topic, payload)?;
        let stamp_ns = header.header.stamp_ns;
        let st = self.stats.entry(topic.to_string()).or_default();
        st.received += 1;
        st.in_window += 1;
        if stamp_ns > 0 {
            let lat = (receipt_ns - stamp_ns) as f64 * 1e-9;
            if lat.is_finite() && lat > -1.0 && lat < 3600.0 {
                st.latency_sum_s += lat;
                st.latency_n += 1;
            }
        }
        let items = self.items(topic, type_name, payload, receipt_ns)?;
        Ok(Mapped { stamp_ns, items })
    }

    fn items(
        &mut self,
        topic: &str,
        t: &str,
        payload: &[u8],
        receipt_ns: i64,
    ) -> Result<Vec<Logged>, MapError> {
        let mut out = Vec::new();
        if t == vision::RgbdFrame::TYPE_NAME {
            let m: vision::RgbdFrame = decode(topic, payload)?;
            self.rgbd(topic, m, receipt_ns, &mut out)?;
        } else if t == body::JointStates::TYPE_NAME {
            let m: body::JointStates = decode(topic, payload)?;
            self.joint_states(&m, &mut out);
        } else if t == tracking::BallTrack::TYPE_NAME {
            let m: tracking::BallTrack = decode(topic, payload)?;
            self.ball_track(&m, &mut out);
        } else if t == tracking::SimBall::TYPE_NAME {
            let m: tracking::SimBall = decode(topic, payload)?;
            if m.present {
                out.push(Logged::new(
                    "world/sim/ball",
                    rerun::Points3D::new([v3(m.centre_world_m)])
                        .with_radii([(m.diameter_m / 2.0) as f32])
                        .with_colors([rerun::Color::from_unmultiplied_rgba(40, 200, 60, 120)])
                        .with_labels([if m.held { "held" } else { "free" }]),
                ));
            } else {
                out.push(Logged::new("world/sim/ball", rerun::Clear::flat()));
            }
        } else if t == tracking::BallTruth::TYPE_NAME {
            let m: tracking::BallTruth = decode(topic, payload)?;
            out.push(Logged::new(
                "world/sim/ball_truth",
                rerun::Points3D::new([v3(m.centre_world_m)])
                    .with_radii([(m.diameter_m / 2.0) as f32])
                    .with_colors([rerun::Color::from_unmultiplied_rgba(40, 200, 60, 90)]),
            ));
        } else if t == tracking::BallEvent::TYPE_NAME {
            let m: tracking::BallEvent = decode(topic, payload)?;
            out.push(Logged::new(
                "log/vision/ball",
                text(format!(
                    "ball {:?} at frame {} (tracker {:?})",
                    m.kind, m.frame_seq, m.state
                )),
            ));
        } else if t == tracking::BallTarget::TYPE_NAME {
            let m: tracking::BallTarget = decode(topic, payload)?;
            out.push(Logged::new(
                "log/vision/ball",
                text(if m.active {
                    format!(
                        "target: hue {:.1} deg, saturation {:.2}, diameter {:.3} m",
                        m.hue_deg, m.saturation, m.diameter_m
                    )
                } else {
                    "target cleared".to_string()
                }),
            ));
        } else if t == body::ReachGoal::TYPE_NAME {
            let m: body::ReachGoal = decode(topic, payload)?;
            self.reach_goal(&m, &mut out);
        } else if t == body::ReachStatus::TYPE_NAME {
            let m: body::ReachStatus = decode(topic, payload)?;
            self.reach_status(&m, &mut out);
        } else if t == executive::StateTransition::TYPE_NAME {
            let m: executive::StateTransition = decode(topic, payload)?;
            out.push(Logged::new(
                format!("log/executive/{}", path_part(&m.machine)),
                text(format!(
                    "#{} {}: exit [{}] enter [{}]; active [{}]",
                    m.step,
                    m.event,
                    m.exited.join(", "),
                    m.entered.join(", "),
                    m.active.join(", ")
                )),
            ));
        } else if t == executive::GameLog::TYPE_NAME {
            let m: executive::GameLog = decode(topic, payload)?;
            out.push(Logged::new(
                "log/game",
                text(format!("[{}] {}: {}", m.machine, m.kind, m.text)),
            ));
        } else if t == speech::Utterance::TYPE_NAME {
            let m: speech::Utterance = decode(topic, payload)?;
            out.push(Logged::new(
                "log/speech/heard",
                text(format!(
                    "\"{}\" confidence {:.2} -> {:?}{}",
                    m.text,
                    m.confidence,
                    m.command,
                    if m.in_grammar {
                        ""
                    } else {
                        " (out of grammar)"
                    }
                )),
            ));
        } else if t == speech::ListeningDirection::TYPE_NAME {
            // Where the recognizer's beam listens and where the sound it hears comes from, as
            // curves over time (degrees of the array's frame, positive to the left): hers and
            // someone else's apart.
            let m: speech::ListeningDirection = decode(topic, payload)?;
            let array = path_part(&m.header.frame_id);
            out.push(Logged::new(
                format!("hearing/{array}/beam_azimuth_deg"),
                rerun::Scalars::single(m.beam_azimuth_rad.to_degrees()),
            ));
            if m.located {
                let whose = if m.elsewhere { "someone_else" } else { "her" };
                out.push(Logged::new(
                    format!("hearing/{array}/{whose}_azimuth_deg"),
                    rerun::Scalars::single(m.talker_azimuth_rad.to_degrees()),
                ));
            }
        } else if t == speech::SayRequest::TYPE_NAME {
            let m: speech::SayRequest = decode(topic, payload)?;
            out.push(Logged::new(
                "log/speech/say",
                text(format!("#{} ({:?}) \"{}\"", m.id, m.priority, m.text)),
            ));
        } else if t == speech::SpeakingEvent::TYPE_NAME {
            let m: speech::SpeakingEvent = decode(topic, payload)?;
            let line = format!("#{} {:?} \"{}\" {}", m.id, m.state, m.text, m.detail);
            let failed = matches!(
                m.state,
                speech::SpeakingState::Failed | speech::SpeakingState::Dropped
            );
            out.push(Logged::new(
                "log/speech/speaking",
                if failed { warn(line) } else { text(line) },
            ));
        } else if t == command::GameCommand::TYPE_NAME {
            let m: command::GameCommand = decode(topic, payload)?;
            out.push(Logged::new(
                "log/dialog/command",
                text(format!(
                    "{:?} {:?} from {:?} \"{}\" (confidence {:.2}{})",
                    m.game,
                    m.command,
                    m.source,
                    m.text,
                    m.confidence,
                    if m.confirmed { ", confirmed" } else { "" }
                )),
            ));
        } else if t == command::Answer::TYPE_NAME {
            let m: command::Answer = decode(topic, payload)?;
            out.push(Logged::new(
                "log/dialog/answer",
                text(if m.yes { "yes" } else { "no" }),
            ));
        } else if t == dr::DrChange::TYPE_NAME {
            let m: dr::DrChange = decode(topic, payload)?;
            self.dr_change(&m, &mut out);
        } else if t == dr::SnapshotData::TYPE_NAME {
            let m: dr::SnapshotData = decode(topic, payload)?;
            self.dr_snapshot(&m, &mut out);
        } else if t == diag::Diagnostics::TYPE_NAME {
            let m: diag::Diagnostics = decode(topic, payload)?;
            for c in &m.counters {
                out.push(Logged::new(
                    format!(
                        "diagnostics/{}/{}",
                        path_part(&m.component),
                        path_part(&c.name)
                    ),
                    rerun::Scalars::single(c.value as f64),
                ));
            }
        } else if t == nao::NaoWorldModel::TYPE_NAME {
            let m: nao::NaoWorldModel = decode(topic, payload)?;
            self.field_lines(&mut out);
            self.world_model(&m, &mut out);
        } else if t == nao::NaoLocalModel::TYPE_NAME {
            let m: nao::NaoLocalModel = decode(topic, payload)?;
            self.field_lines(&mut out);
            self.local_model(&m, &mut out);
        } else if t == nao::FieldTruth::TYPE_NAME {
            let m: nao::FieldTruth = decode(topic, payload)?;
            self.field_lines(&mut out);
            let robots = [m.controlled, m.teammate];
            field_poses(
                &mut out,
                "truth/robots",
                &robots,
                &["controlled", "teammate"],
                GREY,
            );
            field_points(
                &mut out,
                "truth/ball",
                &[m.ball],
                0.05,
                GREY,
                &["ball (truth)"],
            );
        } else if t == nao::GameState::TYPE_NAME {
            let m: nao::GameState = decode(topic, payload)?;
            let line = format!(
                "state {} set play {} phase {} {} half, {} s left, score {}:{}",
                game_state_name(m.state),
                m.set_play,
                m.game_phase,
                if m.first_half { "first" } else { "second" },
                m.secs_remaining,
                m.our_team.score,
                m.opponent.score
            );
            self.text_on_change("log/nao/game", line, &mut out);
        } else if t == nao::NaoLinkEvent::TYPE_NAME {
            let m: nao::NaoLinkEvent = decode(topic, payload)?;
            let line = format!(
                "robot {}: {:?} (silent {:.1} s)",
                m.player_number, m.change, m.silent_for_s
            );
            out.push(Logged::new(
                "log/nao/link",
                if m.change == nao::LinkChange::RobotNotResponding {
                    warn(line)
                } else {
                    text(line)
                },
            ));
        } else if t == nao::NaoCommand::TYPE_NAME {
            let m: nao::NaoCommand = decode(topic, payload)?;
            out.push(Logged::new(
                "log/nao/command",
                text(format!(
                    "{:?} / head {:?} / {:?} target ({:.0}, {:.0}) mm from {}",
                    m.body, m.head, m.strategy, m.target.x_mm, m.target.y_mm, m.source
                )),
            ));
        } else if t == nao::CoachRequest::TYPE_NAME {
            let m: nao::CoachRequest = decode(topic, payload)?;
            out.push(Logged::new(
                "log/coach/request",
                text(format!(
                    "{:?} / head {:?}{}",
                    m.command.body,
                    m.command.head,
                    if m.aimed {
                        format!(" aimed at ({:.0}, {:.0}) mm", m.aim.x_mm, m.aim.y_mm)
                    } else {
                        String::new()
                    }
                )),
            ));
        } else if t == nao::CoachStatus::TYPE_NAME {
            let m: nao::CoachStatus = decode(topic, payload)?;
            let line = format!(
                "{} (link {}, fallen {}, penalised {}) {}",
                m.state,
                if m.link_up { "up" } else { "down" },
                m.fallen,
                m.penalised,
                m.last_answer
            );
            self.text_on_change("log/coach/status", line, &mut out);
        } else if t == std_msgs::Text::TYPE_NAME {
            let m: std_msgs::Text = decode(topic, payload)?;
            out.push(Logged::new(format!("log/{topic}"), text(m.text)));
        }
        // Other known types (audio, benchmarks, service types on topics): rates only.
        Ok(out)
    }

    fn text_on_change(&mut self, path: &str, line: String, out: &mut Vec<Logged>) {
        if self.last_text.get(path) != Some(&line) {
            self.last_text.insert(path.to_string(), line.clone());
            out.push(Logged::new(path, text(line)));
        }
    }

    /// Per-topic figures since the last call (call about once a second); empty on the first call.
    pub fn figures(&mut self, now_ns: i64) -> Vec<TopicFigures> {
        let dt = (now_ns - self.last_stats_ns) as f64 * 1e-9;
        let first = self.last_stats_ns == 0;
        self.last_stats_ns = now_ns;
        let mut out = Vec::new();
        for (topic, s) in &mut self.stats {
            if !first && dt > 0.0 {
                out.push(TopicFigures {
                    topic: topic.clone(),
                    rate_hz: s.in_window as f64 / dt,
                    latency_ms: (s.latency_n > 0)
                        .then(|| s.latency_sum_s / s.latency_n as f64 * 1e3),
                    thinned: s.thinned,
                });
            }
            s.in_window = 0;
            s.latency_sum_s = 0.0;
            s.latency_n = 0;
        }
        out
    }

    /// [`Mapper::figures`] as scalars: `stats/rate_hz/<topic>`, `stats/latency_ms/<topic>` (mean,
    /// header stamp to receipt), `stats/thinned/<topic>` (camera frames not logged) and
    /// `stats/dropped/<topic>` (totals of the intake): one subtree per figure, one plot each.
    pub fn stats(&mut self, now_ns: i64, dropped: &BTreeMap<String, u64>) -> Vec<Logged> {
        let mut out = Vec::new();
        for f in self.figures(now_ns) {
            let topic = &f.topic;
            out.push(Logged::new(
                format!("stats/rate_hz/{topic}"),
                rerun::Scalars::single(f.rate_hz),
            ));
            if let Some(l) = f.latency_ms {
                out.push(Logged::new(
                    format!("stats/latency_ms/{topic}"),
                    rerun::Scalars::single(l),
                ));
            }
            if f.thinned > 0 {
                out.push(Logged::new(
                    format!("stats/thinned/{topic}"),
                    rerun::Scalars::single(f.thinned as f64),
                ));
            }
        }
        for (topic, n) in dropped {
            out.push(Logged::new(
                format!("stats/dropped/{topic}"),
                rerun::Scalars::single(*n as f64),
            ));
        }
        out
    }

    /// Samples received per topic so far.
    pub fn received(&self) -> BTreeMap<String, u64> {
        self.stats
            .iter()
            .map(|(t, s)| (t.clone(), s.received))
            .collect()
    }
}

fn decode_header(topic: &str, payload: &[u8]) -> Result<HeaderOnly, MapError> {
    codec::decode::<HeaderOnly>(payload, "header").map_err(|source| MapError::Undecodable {
        topic: topic.to_string(),
        source,
    })
}

/// An entity path element from free text (machine names, counters): `/` kept, spaces to `_`.
fn path_part(s: &str) -> String {
    if s.is_empty() {
        return "unnamed".into();
    }
    s.chars()
        .map(|c| {
            if c.is_alphanumeric() || "/_-.".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect()
}

fn mm2(p: [f64; 2]) -> [f32; 2] {
    [(p[0] / 1000.0) as f32, (p[1] / 1000.0) as f32]
}

fn fp(p: &nao::FieldPoint) -> [f32; 2] {
    [p.x_mm / 1000.0, p.y_mm / 1000.0]
}

/// Points on the field, in 2D (`field2d/<name>`, y flipped) and 3D (`field3d/<name>`, z = radius).
fn field_points(
    out: &mut Vec<Logged>,
    name: &str,
    pts: &[nao::FieldPoint],
    radius_m: f32,
    colour: rerun::Color,
    labels: &[&str],
) {
    let p: Vec<[f32; 2]> = pts.iter().map(fp).collect();
    let mut p2 = rerun::Points2D::new(p.iter().map(|q| [q[0], -q[1]]))
        .with_radii([radius_m])
        .with_colors([colour]);
    let mut p3 = rerun::Points3D::new(p.iter().map(|q| [q[0], q[1], radius_m]))
        .with_radii([radius_m])
        .with_colors([colour]);
    if !labels.is_empty() {
        p2 = p2.with_labels(labels.iter().map(|s| s.to_string()));
        p3 = p3.with_labels(labels.iter().map(|s| s.to_string()));
    }
    out.push(Logged::new(format!("field2d/{name}"), p2));
    out.push(Logged::new(format!("field3d/{name}"), p3));
}

/// Robot poses on the field: a point and a 0.3 m heading arrow, in 2D and 3D.
fn field_poses(
    out: &mut Vec<Logged>,
    name: &str,
    poses: &[nao::FieldPose],
    labels: &[&str],
    colour: rerun::Color,
) {
    let pts: Vec<nao::FieldPoint> = poses
        .iter()
        .map(|p| nao::FieldPoint {
            x_mm: p.x_mm,
            y_mm: p.y_mm,
        })
        .collect();
    field_points(out, name, &pts, 0.12, colour, labels);
    let heading: Vec<[f32; 2]> = poses
        .iter()
        .map(|p| [0.3 * p.theta_rad.cos(), 0.3 * p.theta_rad.sin()])
        .collect();
    let origins: Vec<[f32; 2]> = pts.iter().map(fp).collect();
    out.push(Logged::new(
        format!("field2d/{name}/heading"),
        rerun::Arrows2D::from_vectors(heading.iter().map(|v| [v[0], -v[1]]))
            .with_origins(origins.iter().map(|o| [o[0], -o[1]]))
            .with_colors([colour]),
    ));
    out.push(Logged::new(
        format!("field3d/{name}/heading"),
        rerun::Arrows3D::from_vectors(heading.iter().map(|v| [v[0], v[1], 0.0]))
            .with_origins(origins.iter().map(|o| [o[0], o[1], 0.12]))
            .with_colors([colour]),
    ));
}

fn game_state_name(s: u8) -> &'static str {
    match s {
        nao::GameState::INITIAL => "initial",
        nao::GameState::READY => "ready",
        nao::GameState::SET => "set",
        nao::GameState::PLAYING => "playing",
        nao::GameState::FINISHED => "finished",
        _ => "unknown",
    }
}

/// Entity path of every link: `world/robot/<root>/<child>/.../<link>`.
fn link_paths(robot: &RobotModel) -> Vec<String> {
    let mut paths = vec![String::new(); robot.links.len()];
    fn path_of(robot: &RobotModel, i: usize, paths: &mut Vec<String>, depth: usize) -> String {
        if !paths[i].is_empty() {
            return paths[i].clone();
        }
        let name = &robot.links[i].name;
        let p = match robot.links[i].parent_joint {
            Some(j) if depth < robot.links.len() => {
                let parent = robot.joints[j].parent;
                format!("{}/{name}", path_of(robot, parent, paths, depth + 1))
            }
            _ => format!("{ROBOT_ROOT}/{name}"),
        };
        paths[i] = p.clone();
        p
    }
    for i in 0..robot.links.len() {
        path_of(robot, i, &mut paths, 0);
    }
    paths
}

#[cfg(test)]
mod tests;
