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
use world_model::types::ChangeEvent;

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

    /// The whole robot at rest (q = 0 for every movable joint) plus its collision geometry, once.
    fn draw_robot(&mut self, out: &mut Vec<Logged>) {
        if self.robot_drawn {
            return;
        }
        let Some(robot) = &self.robot else { return };
        self.robot_drawn = true;
        for j in &robot.joints {
            let path = &self.link_paths[j.child];
            let iso = j.transform(0.0);
            if j.kind.is_movable() {
                out.push(Logged::new(path.clone(), tr(&iso)));
            } else {
                out.push(Logged::fixed(path.clone(), tr(&iso)));
            }
        }
        let grey = rerun::Color::from_unmultiplied_rgba(160, 160, 175, 160);
        for (li, link) in robot.links.iter().enumerate() {
            for (i, c) in link.collision.iter().enumerate() {
                let path = format!("{}/collision/{i}", self.link_paths[li]);
                let shape: Option<Box<dyn AsComponents + Send>> = match &c.shape {
                    Shape::Box { size_m } => Some(Box::new(
                        rerun::Boxes3D::from_sizes([v3(*size_m)]).with_colors([grey]),
                    )),
                    Shape::Cylinder { radius_m, length_m } => Some(Box::new(
                        rerun::Cylinders3D::from_lengths_and_radii(
                            [*length_m as f32],
                            [*radius_m as f32],
                        )
                        .with_colors([grey]),
                    )),
                    Shape::Capsule { radius_m, length_m } => Some(Box::new(
                        // rerun's capsule runs from its origin along +z; URDF's is centred.
                        rerun::Capsules3D::from_lengths_and_radii(
                            [*length_m as f32],
                            [*radius_m as f32],
                        )
                        .with_translations([[0.0, 0.0, -(*length_m as f32) / 2.0]])
                        .with_colors([grey]),
                    )),
                    Shape::Sphere { radius_m } => Some(Box::new(
                        rerun::Ellipsoids3D::from_radii([*radius_m as f32]).with_colors([grey]),
                    )),
                    // Meshes are not drawn (robocog does no mesh collision either).
                    Shape::Mesh { .. } => None,
                };
                if let Some(data) = shape {
                    out.push(Logged::fixed(path.clone(), tr(&c.origin)));
                    out.push(Logged {
                        path,
                        is_static: true,
                        data,
                    });
                }
            }
        }
    }

    fn joint_states(&mut self, m: &body::JointStates, out: &mut Vec<Logged>) {
        self.draw_robot(out);
        let Some(robot) = &self.robot else { return };
        for js in &m.joints {
            let Ok(j) = robot.joint(&js.name) else {
                continue;
            };
            if !js.position.is_finite() {
                continue;
            }
            out.push(Logged::new(
                self.link_paths[j.child].clone(),
                tr(&j.transform(js.position)),
            ));
        }
    }

    fn rgbd(
        &mut self,
        topic: &str,
        m: vision::RgbdFrame,
        receipt_ns: i64,
        out: &mut Vec<Logged>,
    ) -> Result<(), MapError> {
        if !m.is_consistent() {
            return Err(MapError::Invalid {
                topic: topic.to_string(),
                reason: format!(
                    "frame {}x{} with {} RGB and {} depth bytes",
                    m.width,
                    m.height,
                    m.rgb.len(),
                    m.depth_mm.len()
                ),
            });
        }
        if self.options.image_hz > 0.0 {
            let st = self.stats.entry(topic.to_string()).or_default();
            let min_gap = (1e9 / self.options.image_hz) as i64;
            if st.last_image_ns != 0 && receipt_ns - st.last_image_ns < min_gap {
                st.thinned += 1;
                return Ok(());
            }
            st.last_image_ns = receipt_ns;
        }
        self.draw_robot(out);
        let cam = self.camera_path(&m.header.frame_id);
        let mut k = [
            m.intrinsics.fx,
            m.intrinsics.fy,
            m.intrinsics.cx,
            m.intrinsics.cy,
        ];
        if !(k[0] > 0.0 && k[1] > 0.0)
            && let Some(c) = self
                .robot
                .as_ref()
                .and_then(|r| r.cameras.iter().find(|c| c.frame == m.header.frame_id))
        {
            k = [c.fx, c.fy, c.cx, c.cy];
        }
        if k[0] > 0.0 && k[1] > 0.0 && self.pinholes.get(&cam) != Some(&(m.width, m.height, k)) {
            self.pinholes.insert(cam.clone(), (m.width, m.height, k));
            out.push(Logged::new(
                cam.clone(),
                rerun::Pinhole::from_focal_length_and_resolution(
                    [k[0] as f32, k[1] as f32],
                    [m.width as f32, m.height as f32],
                )
                .with_principal_point([k[2] as f32, k[3] as f32])
                .with_image_plane_distance(0.5),
            ));
        }
        let res = [m.width, m.height];
        out.push(Logged::new(
            format!("{cam}/rgb"),
            rerun::Image::from_rgb24(m.rgb, res),
        ));
        out.push(Logged::new(
            format!("{cam}/depth"),
            rerun::DepthImage::from_gray16(m.depth_mm, res).with_meter(1000.0),
        ));
        Ok(())
    }

    fn push_trajectory(&mut self, path: &str, p: [f32; 3], out: &mut Vec<Logged>) {
        let cap = self.options.trajectory_len.max(2);
        let tr = self.trajectories.entry(path.to_string()).or_default();
        tr.push_back(p);
        while tr.len() > cap {
            tr.pop_front();
        }
        if tr.len() >= 2 {
            let strip: Vec<[f32; 3]> = tr.iter().copied().collect();
            out.push(Logged::new(
                format!("{path}/trajectory"),
                rerun::LineStrips3D::new([strip])
                    .with_colors([ORANGE])
                    .with_radii([0.004]),
            ));
        }
    }

    fn ball_track(&mut self, m: &tracking::BallTrack, out: &mut Vec<Logged>) {
        let cam = self.camera_path(&m.header.frame_id);
        let window = format!("{cam}/ball_window");
        let label = format!("{:?} {:.2}", m.state, m.confidence);
        if m.found {
            let w = m.window;
            out.push(Logged::new(
                window,
                rerun::Boxes2D::from_mins_and_sizes(
                    [[w.x as f32, w.y as f32]],
                    [[w.width as f32, w.height as f32]],
                )
                .with_colors([YELLOW])
                .with_labels([label.clone()]),
            ));
        } else {
            out.push(Logged::new(window, rerun::Clear::flat()));
        }
        let r = (m.diameter_m / 2.0).max(0.01) as f32;
        if m.found && m.has_centre_world {
            let p = v3(m.centre_world_m);
            out.push(Logged::new(
                "world/ball",
                rerun::Points3D::new([p])
                    .with_radii([r])
                    .with_colors([ORANGE])
                    .with_labels([label]),
            ));
            self.push_trajectory("world/ball", p, out);
        } else if m.found && m.has_centre_m {
            let path = format!("{}/ball", self.frame_path(&m.header.frame_id));
            let p = v3(m.centre_m);
            out.push(Logged::new(
                path.clone(),
                rerun::Points3D::new([p])
                    .with_radii([r])
                    .with_colors([ORANGE])
                    .with_labels([label]),
            ));
            self.push_trajectory(&path, p, out);
        }
    }

    fn reach_goal(&mut self, m: &body::ReachGoal, out: &mut Vec<Logged>) {
        let part = path_part(&m.body_part);
        out.push(Logged::new(
            "log/reach",
            text(if m.active {
                format!(
                    "goal #{} from {}: {} {:?} to {:?} in {}{}",
                    m.id,
                    m.client,
                    m.body_part,
                    m.kind,
                    m.position_m,
                    m.frame,
                    if m.follow { " (follow)" } else { "" }
                )
            } else {
                format!("goal #{} from {}: cancel {}", m.id, m.client, m.body_part)
            }),
        ));
        let path = format!("world/reach/{part}/goal");
        if m.active && m.frame == "world" {
            out.push(Logged::new(
                path,
                rerun::Points3D::new([v3(m.position_m)])
                    .with_radii([0.015])
                    .with_colors([BLUE])
                    .with_labels([format!("goal #{}", m.id)]),
            ));
        } else if !m.active {
            out.push(Logged::new(path, rerun::Clear::flat()));
        }
    }

    fn reach_status(&mut self, m: &body::ReachStatus, out: &mut Vec<Logged>) {
        use body::ReachState as S;
        let part = path_part(&m.body_part);
        let colour = match m.state {
            S::Moving => YELLOW,
            S::Reached => GREEN,
            S::Unreachable => RED,
            S::Cancelled => GREY,
            S::Failed => rerun::Color::from_rgb(200, 0, 200),
        };
        let label = format!("#{} {:?}", m.id, m.state);
        let line = format!(
            "#{} {} {:?}: residual {:.3} m, distance {:.3} m {}",
            m.id, m.body_part, m.state, m.residual_m, m.distance_m, m.detail
        );
        out.push(Logged::new(
            "log/reach",
            if matches!(m.state, S::Unreachable | S::Failed) {
                warn(line)
            } else {
                text(line)
            },
        ));
        if matches!(m.state, S::Cancelled | S::Failed) {
            return;
        }
        out.push(Logged::new(
            format!("world/reach/{part}/target"),
            rerun::Points3D::new([v3(m.target_world_m)])
                .with_radii([0.02])
                .with_colors([colour])
                .with_labels([label.clone()]),
        ));
        out.push(Logged::new(
            format!("world/reach/{part}/tip"),
            rerun::Points3D::new([v3(m.tip_world_m)])
                .with_radii([0.01])
                .with_colors([colour]),
        ));
        if matches!(m.state, S::Reached | S::Unreachable) {
            // A lasting mark where the outcome happened.
            out.push(Logged::new(
                format!(
                    "world/reach/{part}/{}",
                    if m.state == S::Reached {
                        "reached"
                    } else {
                        "unreachable"
                    }
                ),
                rerun::Points3D::new([v3(m.target_world_m)])
                    .with_radii([0.025])
                    .with_colors([colour])
                    .with_labels([label]),
            ));
        }
    }

    /// The field's lines, once: `field3d/lines` (m, z = 0) and `field2d/lines` (m, y flipped).
    fn field_lines(&mut self, out: &mut Vec<Logged>) {
        if self.field_drawn {
            return;
        }
        let Some(f) = &self.field else { return };
        self.field_drawn = true;
        let mut strips: Vec<Vec<[f32; 2]>> =
            f.lines().iter().map(|l| vec![mm2(l.a), mm2(l.b)]).collect();
        let r = f.center_circle_diameter_mm as f32 / 2000.0;
        strips.push(
            (0..=48)
                .map(|i| {
                    let a = i as f32 / 48.0 * std::f32::consts::TAU;
                    [r * a.cos(), r * a.sin()]
                })
                .collect(),
        );
        let s3: Vec<Vec<[f32; 3]>> = strips
            .iter()
            .map(|s| s.iter().map(|p| [p[0], p[1], 0.0]).collect())
            .collect();
        let s2: Vec<Vec<[f32; 2]>> = strips
            .iter()
            .map(|s| s.iter().map(|p| [p[0], -p[1]]).collect())
            .collect();
        let w = f.line_width_mm as f32 / 2000.0;
        out.push(Logged::fixed(
            "field3d/lines",
            rerun::LineStrips3D::new(s3)
                .with_colors([WHITE])
                .with_radii([w]),
        ));
        out.push(Logged::fixed(
            "field2d/lines",
            rerun::LineStrips2D::new(s2)
                .with_colors([WHITE])
                .with_radii([w]),
        ));
        let posts: Vec<[f32; 2]> = f
            .landmarks
            .iter()
            .filter(|l| l.class == "goalpost")
            .map(|l| mm2([l.x_mm, l.y_mm]))
            .collect();
        let post_r = f.goalpost_diameter_mm as f32 / 2000.0;
        out.push(Logged::fixed(
            "field3d/goalposts",
            rerun::Points3D::new(posts.iter().map(|p| [p[0], p[1], 0.0]))
                .with_radii([post_r])
                .with_colors([WHITE]),
        ));
        out.push(Logged::fixed(
            "field2d/goalposts",
            rerun::Points2D::new(posts.iter().map(|p| [p[0], -p[1]]))
                .with_radii([post_r])
                .with_colors([WHITE]),
        ));
    }

    fn world_model(&mut self, m: &nao::NaoWorldModel, out: &mut Vec<Logged>) {
        let poses: Vec<nao::FieldPose> = m.robots.iter().map(|r| r.pose).collect();
        let labels: Vec<String> = m
            .robots
            .iter()
            .map(|r| {
                format!(
                    "#{} role {}{}",
                    r.player_number,
                    r.role,
                    if r.fallen { " FALLEN" } else { "" }
                )
            })
            .collect();
        let labels: Vec<&str> = labels.iter().map(String::as_str).collect();
        field_poses(out, "robots", &poses, &labels, BLUE);
        if m.ball_known {
            field_points(
                out,
                "ball",
                &[m.ball],
                0.05,
                ORANGE,
                &[&format!("ball ({:.1} s)", m.ball_age_s)],
            );
        } else {
            out.push(Logged::new("field2d/ball", rerun::Clear::flat()));
            out.push(Logged::new("field3d/ball", rerun::Clear::flat()));
        }
        let obstacles: Vec<nao::FieldPoint> = m.obstacles.iter().map(|o| o.center).collect();
        field_points(out, "obstacles", &obstacles, 0.15, RED, &[]);
    }

    fn local_model(&mut self, m: &nao::NaoLocalModel, out: &mut Vec<Logged>) {
        let n = m.player_number;
        field_poses(
            out,
            &format!("local/{n}/pose"),
            &[m.pose],
            &[&format!("#{n} (own estimate)")],
            rerun::Color::from_rgb(120, 170, 255),
        );
        field_points(
            out,
            &format!("local/{n}/ball"),
            &[m.ball],
            0.04,
            YELLOW,
            &[],
        );
        field_points(
            out,
            "team_ball",
            &[m.team_ball],
            0.05,
            ORANGE,
            &["team ball"],
        );
        let seen: Vec<nao::FieldPoint> = m.obstacles.iter().map(|o| o.center).collect();
        field_points(out, &format!("local/{n}/obstacles"), &seen, 0.1, RED, &[]);
    }

    /// Whether the DR mirror needs a `dr/snapshot` (none yet, or changes it could not apply).
    pub fn wants_dr_snapshot(&self) -> bool {
        self.dr.wants_snapshot
    }

    fn dr_snapshot(&mut self, m: &dr::SnapshotData, out: &mut Vec<Logged>) {
        match SceneGraph::restore_json(&m.json) {
            Ok(g) => {
                self.dr.graph = Some(g);
                self.dr.last_seq = m.last_seq;
                self.dr.wants_snapshot = false;
                self.dr.dirty = true;
                out.push(Logged::new(
                    "log/dr",
                    text(format!(
                        "snapshot: {} nodes, up to change #{}",
                        m.nodes, m.last_seq
                    )),
                ));
            }
            Err(e) => out.push(Logged::new(
                "log/dr",
                warn(format!("snapshot not usable: {e}")),
            )),
        }
    }

    fn dr_change(&mut self, m: &dr::DrChange, out: &mut Vec<Logged>) {
        // Joint values follow the joint states at 100 Hz: not worth a text line each.
        if m.kind != "joint_set" {
            out.push(Logged::new(
                "log/dr",
                text(format!("#{} {} {}", m.seq, m.kind, m.node)),
            ));
        }
        let Some(g) = &mut self.dr.graph else {
            self.dr.wants_snapshot = true;
            return;
        };
        if m.seq <= self.dr.last_seq {
            return; // already in the snapshot
        }
        if m.kind == "restored" || m.seq != self.dr.last_seq + 1 {
            self.dr.wants_snapshot = true;
            self.dr.last_seq = m.seq;
            return;
        }
        self.dr.last_seq = m.seq;
        let applied = serde_json::from_str::<ChangeEvent>(&m.event_json)
            .map_err(|e| e.to_string())
            .and_then(|ev| g.apply(&ev).map_err(|e| e.to_string()));
        match applied {
            Ok(()) => self.dr.dirty = true,
            Err(e) => {
                self.dr.wants_snapshot = true;
                out.push(Logged::new(
                    "log/dr",
                    warn(format!(
                        "change #{} not applied to the viewer's copy: {e}",
                        m.seq
                    )),
                ));
            }
        }
    }

    /// The DR's nodes, if they changed and the last drawing is older than [`DR_DRAW_EVERY_NS`]:
    /// each node at `dr/nodes/<name>` (`world_T_node` as a Transform3D, a labelled point), the
    /// edges as `dr/edges` (parent to child, in the world). Call often (every sample is fine).
    pub fn dr_draw(&mut self, now_ns: i64) -> Vec<Logged> {
        let mut out = Vec::new();
        if !self.dr.dirty || now_ns - self.dr.last_draw_ns < DR_DRAW_EVERY_NS {
            return out;
        }
        let Some(g) = &self.dr.graph else {
            return out;
        };
        self.dr.dirty = false;
        self.dr.last_draw_ns = now_ns;
        let mut drawn: HashMap<String, [f32; 7]> = HashMap::new();
        let mut edges: Vec<Vec<[f32; 3]>> = Vec::new();
        let mut world: HashMap<String, [f32; 3]> = HashMap::new();
        for (_, n) in g.nodes() {
            let Ok(w) = g.transform("world", &n.name, At::Latest) else {
                continue;
            };
            let t = w.translation.vector;
            let q = w.rotation.coords;
            world.insert(n.name.clone(), [t.x as f32, t.y as f32, t.z as f32]);
            if n.name == "world" {
                continue;
            }
            let key = [t.x, t.y, t.z, q.x, q.y, q.z, q.w].map(|v| v as f32);
            let path = format!("dr/nodes/{}", path_part(&n.name));
            match self.dr.drawn.get(&n.name) {
                // Unchanged since the last drawing: rerun keeps the latest value.
                Some(k) if k == &key => {}
                Some(_) => out.push(Logged::new(path, tr(&w))),
                None => {
                    out.push(Logged::new(path.clone(), tr(&w)));
                    out.push(Logged::new(
                        path,
                        rerun::Points3D::new([[0.0f32, 0.0, 0.0]])
                            .with_radii([0.008])
                            .with_colors([rerun::Color::from_rgb(170, 120, 220)])
                            .with_labels([format!("{} ({})", n.name, n.node_type.name())]),
                    ));
                }
            }
            drawn.insert(n.name.clone(), key);
        }
        for (_, n) in g.nodes() {
            if let Some(p) = n.parent.and_then(|p| g.node_by_id(p))
                && let (Some(a), Some(b)) = (world.get(&p.name), world.get(&n.name))
            {
                edges.push(vec![*a, *b]);
            }
        }
        out.push(Logged::new(
            "dr/edges",
            rerun::LineStrips3D::new(edges)
                .with_radii([0.002])
                .with_colors([rerun::Color::from_rgb(170, 120, 220)]),
        ));
        for gone in self.dr.drawn.keys().filter(|d| !drawn.contains_key(*d)) {
            out.push(Logged::new(
                format!("dr/nodes/{}", path_part(gone)),
                rerun::Clear::flat(),
            ));
        }
        self.dr.drawn = drawn;
        out
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
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use interfaces::msg::vision::Intrinsics;

    const S: i64 = 1_000_000_000;

    fn loki() -> RobotModel {
        RobotModel::from_urdf_file(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../models/loki.urdf"
        ))
        .unwrap()
    }

    fn field() -> FieldModel {
        FieldModel::from_file(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../models/spl_field.toml"
        ))
        .unwrap()
    }

    fn mapper() -> Mapper {
        Mapper::new(Some(loki()), Some(field()), MapperOptions::default())
    }

    fn enc<T: Message>(m: &T) -> Vec<u8> {
        codec::encode(m, T::TYPE_NAME).unwrap()
    }

    fn stamped<T: Message>(mut m: T, stamp_ns: i64) -> T {
        m.header_mut().stamp_ns = stamp_ns;
        m
    }

    fn map<T: Message>(mp: &mut Mapper, topic: &str, m: &T, at: i64) -> Vec<Logged> {
        mp.map(topic, T::TYPE_NAME, &enc(m), at).unwrap().items
    }

    fn find<'a>(items: &'a [Logged], path_end: &str, archetype: &str) -> Option<&'a Logged> {
        items.iter().find(|i| {
            i.path.ends_with(path_end)
                && i.archetypes()
                    .iter()
                    .any(|a| a.ends_with(&format!(".{archetype}")))
        })
    }

    #[test]
    fn joint_states_move_the_links_and_the_collision_geometry_is_drawn_once() {
        let mut mp = mapper();
        let js = body::JointStates {
            joints: vec![body::JointState {
                name: "neck_yaw".into(),
                position: 0.4,
                ..Default::default()
            }],
            ..Default::default()
        };
        let first = map(&mut mp, "body/joint_states", &js, S);
        let head = find(&first, "/neck_roll_link/head", "Transform3D").expect("head link");
        assert!(
            head.path.starts_with("world/robot/base_footprint/"),
            "{}",
            head.path
        );
        let statics = first.iter().filter(|i| i.is_static).count();
        assert!(
            first.iter().any(|i| i.is_static
                && i.path.contains("/collision/")
                && i.archetypes()
                    .iter()
                    .any(|a| a.ends_with("Boxes3D") || a.ends_with("Cylinders3D"))),
            "collision geometry"
        );
        assert!(statics > 10, "{statics} static items");
        let second = map(&mut mp, "body/joint_states", &js, 2 * S);
        assert!(second.iter().all(|i| !i.is_static));
        // Only the joints in the message (and a known URDF joint) are logged after the first.
        assert_eq!(second.len(), 1, "{second:?}");
        // Unknown joints are skipped, not fatal.
        let odd = body::JointStates {
            joints: vec![body::JointState {
                name: "no_such_joint".into(),
                ..Default::default()
            }],
            ..Default::default()
        };
        assert!(map(&mut mp, "body/joint_states", &odd, 3 * S).is_empty());
    }

    fn frame(w: u32, h: u32) -> vision::RgbdFrame {
        let mut f = vision::RgbdFrame::blank(
            w,
            h,
            Intrinsics {
                fx: 100.0,
                fy: 100.0,
                cx: 2.0,
                cy: 1.5,
            },
        );
        f.header.frame_id = "head_rgbd_optical_frame".into();
        f
    }

    #[test]
    fn camera_frames_become_a_pinhole_with_rgb_and_depth_thinned_to_the_image_rate() {
        let mut mp = mapper();
        let cam = mp.head_camera_path();
        assert!(
            cam.ends_with("/head/head_rgbd_link/head_rgbd_optical_frame/camera"),
            "{cam}"
        );
        let items = map(&mut mp, "vision/rgbd", &frame(4, 3), S);
        assert!(find(&items, &cam, "Pinhole").is_some(), "{items:?}");
        assert!(find(&items, &format!("{cam}/rgb"), "Image").is_some());
        assert!(find(&items, &format!("{cam}/depth"), "DepthImage").is_some());
        // 10 Hz: a frame 50 ms later is thinned, one 100 ms later is logged (pinhole unchanged).
        assert!(map(&mut mp, "vision/rgbd", &frame(4, 3), S + S / 20).is_empty());
        let later = map(&mut mp, "vision/rgbd", &frame(4, 3), S + S / 10);
        assert!(find(&later, &cam, "Pinhole").is_none());
        assert!(find(&later, &format!("{cam}/rgb"), "Image").is_some());
        let figs = mp.figures(2 * S);
        let figs = mp
            .figures(3 * S)
            .into_iter()
            .chain(figs)
            .collect::<Vec<_>>();
        assert!(
            figs.iter()
                .any(|f| f.topic == "vision/rgbd" && f.thinned == 1)
        );
    }

    #[test]
    fn bad_samples_are_typed_errors_not_panics() {
        let mut mp = mapper();
        let e = mp
            .map("mystery", "robocog.NoSuchType", &[0, 1, 0, 0], S)
            .unwrap_err();
        assert!(matches!(e, MapError::UnknownType { .. }), "{e}");
        let e = mp
            .map(
                "executive/transitions",
                executive::StateTransition::TYPE_NAME,
                &[0, 1, 0, 0, 9],
                S,
            )
            .unwrap_err();
        assert!(matches!(e, MapError::Undecodable { .. }), "{e}");
        let mut f = frame(4, 3);
        f.rgb.pop();
        let e = mp
            .map("vision/rgbd", vision::RgbdFrame::TYPE_NAME, &enc(&f), S)
            .unwrap_err();
        assert!(matches!(e, MapError::Invalid { .. }), "{e}");
        assert!(e.to_string().contains("4x3"), "{e}");
    }

    #[test]
    fn the_ball_in_the_world_has_a_trajectory_and_the_window_is_on_the_image() {
        let mut mp = mapper();
        let track = |x: f64| tracking::BallTrack {
            header: Header::new("head_rgbd_optical_frame"),
            found: true,
            window: tracking::PixelWindow {
                x: 10,
                y: 20,
                width: 30,
                height: 30,
            },
            has_centre_m: true,
            has_centre_world: true,
            centre_world_m: [x, 0.0, 0.8],
            diameter_m: 0.1,
            state: tracking::BallTrackState::Tracking,
            ..Default::default()
        };
        let a = map(&mut mp, "vision/ball", &track(0.5), S);
        assert!(find(&a, "world/ball", "Points3D").is_some());
        assert!(
            find(
                &a,
                &format!("{}/ball_window", mp.head_camera_path()),
                "Boxes2D"
            )
            .is_some()
        );
        assert!(find(&a, "world/ball/trajectory", "LineStrips3D").is_none());
        let b = map(&mut mp, "vision/ball", &track(0.6), 2 * S);
        assert!(find(&b, "world/ball/trajectory", "LineStrips3D").is_some());
        // Lost: the window is cleared.
        let lost = tracking::BallTrack {
            header: Header::new("head_rgbd_optical_frame"),
            ..Default::default()
        };
        let c = map(&mut mp, "vision/ball", &lost, 3 * S);
        assert!(find(&c, "/ball_window", "Clear").is_some(), "{c:?}");
    }

    #[test]
    fn reach_outcomes_leave_marks_and_warnings() {
        let mut mp = mapper();
        let st = body::ReachStatus {
            body_part: "left_arm".into(),
            state: body::ReachState::Unreachable,
            target_world_m: [1.5, 0.0, 0.9],
            ..Default::default()
        };
        let items = map(&mut mp, "body/reach_status", &st, S);
        assert!(find(&items, "world/reach/left_arm/unreachable", "Points3D").is_some());
        assert!(find(&items, "log/reach", "TextLog").is_some());
        let reached = body::ReachStatus {
            state: body::ReachState::Reached,
            ..st
        };
        let items = map(&mut mp, "body/reach_status", &reached, 2 * S);
        assert!(find(&items, "world/reach/left_arm/reached", "Points3D").is_some());
    }

    #[test]
    fn the_nao_world_is_drawn_in_2d_and_3d_with_the_field_lines_once() {
        let mut mp = mapper();
        let wm = nao::NaoWorldModel {
            robots: vec![nao::TeamRobot {
                player_number: 2,
                pose: nao::FieldPose {
                    x_mm: 1000.0,
                    y_mm: -500.0,
                    theta_rad: 0.5,
                },
                ..Default::default()
            }],
            ball_known: true,
            ..Default::default()
        };
        let a = map(&mut mp, "nao/world_model", &wm, S);
        for (p, arch) in [
            ("field2d/lines", "LineStrips2D"),
            ("field3d/lines", "LineStrips3D"),
            ("field2d/robots", "Points2D"),
            ("field3d/robots", "Points3D"),
            ("field2d/robots/heading", "Arrows2D"),
            ("field3d/ball", "Points3D"),
        ] {
            assert!(find(&a, p, arch).is_some(), "{p} {arch}: {a:?}");
        }
        let b = map(&mut mp, "nao/world_model", &wm, 2 * S);
        assert!(find(&b, "field2d/lines", "LineStrips2D").is_none());
    }

    #[test]
    fn text_topics_become_text_logs_and_rates_and_latencies_are_measured() {
        let mut mp = mapper();
        let tr = executive::StateTransition {
            machine: "touch".into(),
            event: "ball_seen".into(),
            ..Default::default()
        };
        mp.figures(S);
        for i in 0..10 {
            // Stamped 20 ms before receipt.
            let at = S + i * S / 10;
            let items = map(
                &mut mp,
                "executive/transitions",
                &stamped(tr.clone(), at - S / 50),
                at,
            );
            assert!(find(&items, "log/executive/touch", "TextLog").is_some());
        }
        let figs = mp.figures(2 * S);
        let f = figs
            .iter()
            .find(|f| f.topic == "executive/transitions")
            .unwrap();
        assert!((f.rate_hz - 10.0).abs() < 1e-9, "{f:?}");
        assert!((f.latency_ms.unwrap() - 20.0).abs() < 1e-6, "{f:?}");
        let items = mp.stats(3 * S, &BTreeMap::from([("vision/rgbd".to_string(), 4)]));
        assert!(find(&items, "stats/rate_hz/executive/transitions", "Scalars").is_some());
        assert!(find(&items, "stats/dropped/vision/rgbd", "Scalars").is_some());
    }

    #[test]
    fn the_dr_copy_follows_the_changes_and_asks_for_a_snapshot_after_a_gap() {
        use world_model::types::Stamp;
        let mut mp = mapper();
        assert!(mp.wants_dr_snapshot());
        let mut g = world_model::scenes::touch_the_ball(&loki(), Stamp(1)).unwrap();
        let snap = dr::SnapshotData {
            json: g.snapshot_json(),
            nodes: g.len() as u32,
            last_seq: 10,
            ..Default::default()
        };
        map(&mut mp, "dr/snapshot", &snap, S);
        assert!(!mp.wants_dr_snapshot());
        let drawn = mp.dr_draw(S);
        let ball = find(&drawn, "dr/nodes/ball", "Transform3D").expect("the ball node");
        assert!(ball.path == "dr/nodes/ball");
        assert!(find(&drawn, "dr/edges", "LineStrips3D").is_some());
        // Nothing changed: nothing to draw.
        assert!(mp.dr_draw(2 * S).is_empty());
        // The ball moves in the DR: change #11 is applied and drawn.
        g.enable_log();
        let pose = Isometry3::translation(0.7, 0.1, 0.9);
        g.set_pose("ball", &pose, Stamp(2)).unwrap();
        let ev = g.take_log().pop().unwrap();
        let change = |seq| dr::DrChange {
            seq,
            kind: "pose_set".into(),
            node: "ball".into(),
            event_json: serde_json::to_string(&ev).unwrap(),
            ..Default::default()
        };
        map(&mut mp, "dr/changes", &change(11), 3 * S);
        assert!(!mp.wants_dr_snapshot());
        let moved = mp.dr_draw(3 * S);
        assert!(find(&moved, "dr/nodes/ball", "Transform3D").is_some());
        // Only what moved is drawn again (the ball, and the edges).
        assert!(
            find(&moved, "dr/nodes/torso", "Transform3D").is_none(),
            "{moved:?}"
        );
        // A gap (#13 after #11): the copy asks for a new snapshot.
        map(&mut mp, "dr/changes", &change(13), 4 * S);
        assert!(mp.wants_dr_snapshot());
    }
}
