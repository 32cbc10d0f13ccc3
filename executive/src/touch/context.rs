//! The touch game's context: what the machine's guards read and how its actions become
//! [`Output`]s.

use std::sync::Arc;
use std::time::Duration;

use interfaces::Header;
use interfaces::msg::body::{JointGoal, JointMode, JointTarget, ReachGoal, ReachKind};
use interfaces::msg::tracking::BallTarget;

use super::{Act, Input, LogLine, Output};
use crate::engine::{Context, Event};
use crate::settings::{JointRest, TouchSettings};

/// The game's context: what the guards read and the actions write.
#[derive(Debug)]
pub struct TouchCtx {
    pub(super) settings: Arc<TouchSettings>,
    /// The scan pattern ([`TouchSettings::scan_pattern`]).
    scan_points: Vec<[f64; 3]>,
    pub(super) outputs: Vec<Output>,
    pub(super) next_id: u64,
    pub(super) arm_goal: u64,
    /// The arm's reaches use the base too ([`Act::UseBase`]; until the arm is home).
    pub(super) with_base: bool,
    pub(super) gaze_goal: u64,
    scan_index: usize,
    pub(super) ball_seen: bool,
    /// The ball's last tracked centre in `world`, and where `ball:moved` last reported it.
    pub(super) ball_world: Option<[f64; 3]>,
    pub(super) ball_reported: Option<[f64; 3]>,
    pub(super) ball_camera_distance: Option<f64>,
    /// Since when the tracker has held the ball without a break while out of sight.
    pub(super) held_out_of_sight_since: Option<Duration>,
    /// Whether the robot is saying a sentence (`speech/speaking`).
    pub(super) robot_talking: bool,
}

impl TouchCtx {
    pub(super) fn new(settings: Arc<TouchSettings>) -> Self {
        TouchCtx {
            scan_points: settings.scan_pattern(),
            settings,
            outputs: Vec::new(),
            next_id: 0,
            arm_goal: 0,
            with_base: false,
            gaze_goal: 0,
            scan_index: 0,
            ball_seen: false,
            ball_world: None,
            ball_reported: None,
            ball_camera_distance: None,
            held_out_of_sight_since: None,
            robot_talking: false,
        }
    }

    /// The body part the arm's reaches use now.
    pub(super) fn arm_part(&self) -> &str {
        if self.with_base {
            &self.settings.arm_with_base
        } else {
            &self.settings.arm
        }
    }

    fn id(&mut self) -> u64 {
        self.next_id += 1;
        self.next_id
    }

    fn log(&mut self, kind: &'static str, text: String, distance_m: f64) {
        self.outputs.push(Output::Log(LogLine {
            kind,
            text,
            distance_m,
        }));
    }

    fn reach(
        &mut self,
        body_part: &str,
        kind: ReachKind,
        frame: &str,
        p: [f64; 3],
        follow: bool,
    ) -> ReachGoal {
        let s = &self.settings;
        ReachGoal {
            header: Header::default(),
            id: 0,
            client: s.client.clone(),
            active: true,
            body_part: body_part.to_string(),
            kind,
            frame: frame.to_string(),
            position_m: p,
            orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
            tolerance_m: if kind == ReachKind::Gaze {
                0.0
            } else {
                s.touch_tolerance_m
            },
            follow,
            min_duration_s: 0.0,
        }
    }

    fn cancel(&mut self, body_part: &str, id: u64) {
        let mut g = self.reach(body_part, ReachKind::Position, "world", [0.0; 3], false);
        g.active = false;
        g.id = id;
        self.outputs.push(Output::CancelReach(g));
    }

    /// A rest goal: `joints` at `rest_max_speed`, then `slow` at `base_rest_max_speed`.
    fn rest_goal(&self, joints: &[JointRest], slow: &[JointRest]) -> JointGoal {
        let s = &self.settings;
        let target = |r: &JointRest, max_speed: f64| JointTarget {
            joint: r.joint.clone(),
            mode: JointMode::Position,
            position: r.position,
            max_speed,
            velocity: 0.0,
        };
        JointGoal {
            header: Header::default(),
            client: s.client.clone(),
            priority: s.rest_priority,
            targets: joints
                .iter()
                .map(|r| target(r, s.rest_max_speed))
                .chain(slow.iter().map(|r| target(r, s.base_rest_max_speed)))
                .collect(),
            release: false,
        }
    }

    fn target(&self, active: bool) -> BallTarget {
        BallTarget {
            header: Header::default(),
            active,
            hue_deg: self.settings.ball_hue_deg,
            saturation: self.settings.ball_saturation,
            diameter_m: self.settings.ball_diameter_m,
        }
    }
}

impl Context<Act, Input> for TouchCtx {
    fn run(&mut self, action: &Act, _event: &Event<Input>) {
        let s = self.settings.clone();
        match *action {
            Act::Say(text, priority) => {
                self.log("said", text.to_string(), -1.0);
                self.outputs.push(Output::Say {
                    text: text.to_string(),
                    priority,
                });
            }
            Act::SendTarget => {
                let t = self.target(true);
                self.outputs.push(Output::SetBallTarget(t));
            }
            Act::ClearTarget => {
                let t = self.target(false);
                self.outputs.push(Output::SetBallTarget(t));
            }
            Act::ScanFromStart => self.scan_index = 0,
            Act::ScanNext => {
                // The settings' check guarantees a point; without one the head stays put.
                let n = self.scan_points.len().max(1);
                let Some(p) = self.scan_points.get(self.scan_index % n).copied() else {
                    return;
                };
                self.scan_index += 1;
                let mut g = self.reach(&s.neck, ReachKind::Gaze, "world", p, false);
                g.id = self.id();
                self.gaze_goal = g.id;
                self.outputs.push(Output::Reach(g));
            }
            Act::GazeAtBall => {
                let mut g = self.reach(&s.neck, ReachKind::Gaze, "ball", [0.0; 3], true);
                g.id = self.id();
                self.gaze_goal = g.id;
                self.outputs.push(Output::Reach(g));
            }
            Act::GazeAtPerson => {
                if s.person_frame.is_empty() {
                    return;
                }
                let mut g = self.reach(&s.neck, ReachKind::Gaze, &s.person_frame, s.face_m, true);
                g.id = self.id();
                self.gaze_goal = g.id;
                self.outputs.push(Output::Reach(g));
            }
            Act::CancelGaze => {
                let id = std::mem::take(&mut self.gaze_goal);
                self.cancel(&s.neck, id);
            }
            Act::ReachBall => {
                let release = JointGoal {
                    header: Header::default(),
                    client: s.client.clone(),
                    priority: s.rest_priority,
                    targets: Vec::new(),
                    release: true,
                };
                self.outputs.push(Output::Release(release));
                let part = self.arm_part().to_string();
                let mut g = self.reach(&part, ReachKind::Position, "ball", s.touch_offset_m, true);
                g.id = self.id();
                self.arm_goal = g.id;
                self.outputs.push(Output::Reach(g));
            }
            Act::UseBase => {
                let id = std::mem::take(&mut self.arm_goal);
                let part = self.arm_part().to_string();
                self.cancel(&part, id);
                self.with_base = true;
            }
            Act::HomeArm => {
                let id = std::mem::take(&mut self.arm_goal);
                let part = self.arm_part().to_string();
                self.cancel(&part, id);
                // The base goes back too when this reach moved it; a robot whose base is not
                // driven never reaches with it, so its rest goals never name the base's joints.
                let base: &[JointRest] = if std::mem::take(&mut self.with_base) {
                    &s.base_rest
                } else {
                    &[]
                };
                let goal = self.rest_goal(&s.arm_rest, base);
                self.outputs.push(Output::Home(goal));
            }
            Act::HeadAhead => {
                let id = std::mem::take(&mut self.gaze_goal);
                self.cancel(&s.neck, id);
                let goal = self.rest_goal(&s.head_rest, &[]);
                self.outputs.push(Output::Home(goal));
            }
            Act::BallSeen(seen) => self.ball_seen = seen,
            Act::Finish => {
                self.log("done", "the game is over".into(), -1.0);
                self.outputs.push(Output::Finish);
            }
        }
    }
}
