//! The simulated camera: its world (a scripted ball, or the one on `sim/ball`), its inputs
//! from the bus, and its loop rendering a frame every period of the component's clock.

use std::time::Duration;

use interfaces::msg::body::JointStates;
use interfaces::msg::tracking::{BallTruth, SimBall};
use interfaces::ratelimit::RateLimiter;
use interfaces::{Bus, Header, Shutdown, topics};

use super::{Config, Outputs};
use camera::RgbdDriver;
use camera::convert::into_msg;
use camera::scenario::{BallGroundTruth, ScenarioSim};
use camera::world::{HeadCamera, WorldSim, frame_stamp_ns, joint_state_fresh};

/// The simulated world a sim frame is rendered from.
#[derive(Debug)]
pub enum SimWorld {
    /// The lab scene with the ball moved by a scenario.
    Scenario(Box<ScenarioSim>),
    /// The game's scene with the ball from `sim/ball`.
    Topic(Box<WorldSim>),
}

impl SimWorld {
    fn set_world_from_optical(&mut self, pose: nalgebra::Isometry3<f64>) {
        match self {
            SimWorld::Scenario(s) => s.set_world_from_optical(pose),
            SimWorld::Topic(s) => s.set_world_from_optical(pose),
        }
    }

    fn truth(&self) -> Option<BallGroundTruth> {
        match self {
            SimWorld::Scenario(s) => s.truth(),
            SimWorld::Topic(s) => s.truth(),
        }
    }

    fn next_frame(&mut self, now_s: f64) -> Result<Option<camera::Frame>, camera::DriverError> {
        match self {
            SimWorld::Scenario(s) => s.next_frame(now_s),
            SimWorld::Topic(s) => s.next_frame(now_s),
        }
    }
}

/// The sim's inputs from the bus and what to say about them.
struct SimInputs {
    joints: Option<interfaces::Subscriber<JointStates>>,
    balls: Option<interfaces::Subscriber<SimBall>>,
    first_joint_state: bool,
    missing_reported: bool,
    warn_limit: RateLimiter,
}

impl SimInputs {
    /// Applies the newest joint state (if any since the last call) to `head`; its stamp.
    fn update_head(&mut self, bus: &Bus, head: &mut HeadCamera) -> Option<i64> {
        let states = self.joints.as_ref()?.latest()?;
        let report = head.apply(&states);
        if self.first_joint_state {
            self.first_joint_state = false;
            let p = head.world_from_optical().translation.vector;
            tracing::info!(
                "first joint state (driver {:?}): the camera now follows body/joint_states, at \
                 ({:.3}, {:.3}, {:.3}) m in the world",
                states.driver,
                p.x,
                p.y,
                p.z
            );
        }
        if !report.missing.is_empty() && !self.missing_reported {
            self.missing_reported = true;
            tracing::warn!(
                "body/joint_states does not name {}: they stay at their previous value (the rest \
                 posture until named)",
                report.missing.join(", ")
            );
        }
        let counters = bus.counters();
        if !report.non_finite.is_empty() || !report.clamped.is_empty() {
            if !report.non_finite.is_empty() {
                counters.incr("joint_states_non_finite");
            }
            if !report.clamped.is_empty() {
                counters.incr("joint_states_clamped");
            }
            #[expect(
                clippy::disallowed_methods,
                reason = "the log limiter paces what a person reads, on the wall"
            )]
            let allowed = self.warn_limit.allow(std::time::Instant::now());
            if let Some(suppressed) = allowed {
                tracing::warn!(
                    suppressed,
                    "joint state seq {}: ignored non-finite {:?}, clamped into the URDF limits {:?}",
                    states.header.seq,
                    report.non_finite,
                    report.clamped
                );
            }
        }
        Some(states.header.stamp_ns)
    }
}

fn truth_msg(t: &BallGroundTruth, stamp_ns: i64, frame_seq: u64, frame_id: &str) -> BallTruth {
    BallTruth {
        header: Header {
            stamp_ns,
            seq: 0,
            frame_id: frame_id.to_string(),
        },
        frame_seq,
        centre_m: t.centre_camera_m,
        centre_world_m: t.centre_world_m,
        diameter_m: t.diameter_m,
        in_view: t.in_view,
    }
}

/// Queue depth of the sim's inputs: joint states at 100 Hz or more are drained every frame.
const INPUT_QUEUE: usize = 64;

/// How long a (re)started simulated camera waits for the world it films (the ball on
/// `sim/ball`, the head's pose on `body/joint_states`) before it renders without them.
const WORLD_WAIT: Duration = Duration::from_secs(2);

/// The simulated camera's loop: a frame every `period_s` on the component's clock, until
/// shutdown (or a scenario's end).
pub(super) async fn run_sim(
    bus: &Bus,
    config: &Config,
    mut world: SimWorld,
    mut head: Option<HeadCamera>,
    period_s: f64,
    out: Outputs,
    shutdown: &mut Shutdown,
) -> anyhow::Result<()> {
    let Outputs {
        mut kinect_sim,
        frames,
        truths,
        mut status,
    } = out;
    let mut inputs = SimInputs {
        joints: match head {
            Some(_) => Some(
                bus.subscriber_named::<JointStates>(topics::BODY_JOINT_STATES.name(), INPUT_QUEUE)
                    .await?,
            ),
            None => None,
        },
        balls: if config.ball_from_topic {
            Some(
                bus.subscriber_named::<SimBall>(topics::SIM_BALL.name(), INPUT_QUEUE)
                    .await?,
            )
        } else {
            None
        },
        first_joint_state: true,
        missing_reported: false,
        warn_limit: RateLimiter::new(Duration::from_secs(1)),
    };
    let mut last_ns = 0i64;
    let mut joint_stamp: Option<i64> = None;
    // A restarted camera renders nothing before it knows the world it films: a frame without
    // the ball, or seen from the rest posture, would tell the tracker the ball is gone. A real
    // camera sees the ball from its first frame; the simulator must not differ by its own
    // start-up. Past WORLD_WAIT (no simulated person, no joints) it renders what it has.
    let started = bus.clock().now();
    let mut ball_known = !config.ball_from_topic;
    let mut waiting_for_world = true;
    // A frame every period of the component's clock; missed ticks are skipped.
    let mut tick = bus.clock().interval(Duration::from_secs_f64(period_s));
    loop {
        tokio::select! {
            biased;
            _ = shutdown.wait() => return Ok(()),
            _ = tick.tick() => {}
        }
        if let Some(h) = head.as_mut() {
            if let Some(t) = inputs.update_head(bus, h) {
                joint_stamp = Some(t);
            }
            world.set_world_from_optical(h.world_from_optical());
        }
        if let (Some(sub), SimWorld::Topic(w)) = (&inputs.balls, &mut world)
            && let Some(ball) = sub.latest()
        {
            w.set_ball(ball);
            ball_known = true;
        }
        if waiting_for_world {
            let pose_known = head.is_none() || joint_stamp.is_some();
            if ball_known && pose_known {
                waiting_for_world = false;
                tracing::info!("the ball and the head's pose are known: rendering");
            } else if bus.clock().elapsed(started) >= WORLD_WAIT {
                waiting_for_world = false;
                tracing::warn!(
                    "no {} after {:.0} s: rendering without",
                    if ball_known {
                        "joint state"
                    } else if pose_known {
                        "ball on sim/ball"
                    } else {
                        "ball on sim/ball nor joint state"
                    },
                    WORLD_WAIT.as_secs_f64()
                );
            } else {
                continue;
            }
        }
        let now_ns = bus.clock().now_ns();
        if let Some(t) = joint_stamp
            && !joint_state_fresh(now_ns, t)
        {
            bus.counters().incr("joint_states_stale_frames");
            #[expect(
                clippy::disallowed_methods,
                reason = "the log limiter paces what a person reads, on the wall"
            )]
            let allowed = inputs.warn_limit.allow(std::time::Instant::now());
            if let Some(suppressed) = allowed {
                tracing::warn!(
                    suppressed,
                    "the newest joint state is {:.2} s old (stalled publisher, or another \
                     clock): frames are stamped with the bus clock, the camera pose held",
                    (now_ns - t) as f64 * 1e-9
                );
            }
        }
        let stamp_ns = frame_stamp_ns(now_ns, joint_stamp, last_ns);
        last_ns = stamp_ns;
        let Some(frame) = world.next_frame(stamp_ns as f64 * 1e-9)? else {
            return Ok(());
        };
        if let Some(sim) = kinect_sim.as_mut() {
            // The simulated Kinect: the frame goes through fakenect to the driver.
            let pose = head
                .as_ref()
                .map(HeadCamera::world_from_optical)
                .unwrap_or_else(|| config.camera_pose.world_from_optical());
            let up = pose.rotation.inverse() * nalgebra::Vector3::z() * 9.80665;
            let offer = sim.offer(&frame, now_ns as f64 * 1e-9, [up.x, up.y, up.z])?;
            if offer == freenect::fakenect::Offer::ReaderBehind {
                bus.counters().incr("kinect_sim_dropped");
            }
            if let (Some(p), Some(t), freenect::fakenect::Offer::Sent) =
                (&truths, world.truth(), offer)
            {
                let mut truth = truth_msg(&t, stamp_ns, sim.sent, &config.frame_id);
                p.publish(&mut truth).await?;
            }
            continue;
        }
        let Some(frames) = &frames else {
            continue;
        };
        if let Some(s) = status.as_mut() {
            s.frame(true, "the simulated camera").await?;
        }
        let mut msg = into_msg(frame, &config.frame_id);
        msg.header.stamp_ns = stamp_ns;
        frames.publish(&mut msg).await?;
        if let (Some(p), Some(t)) = (&truths, world.truth()) {
            p.publish(&mut truth_msg(
                &t,
                msg.header.stamp_ns,
                msg.header.seq,
                &msg.header.frame_id,
            ))
            .await?;
        }
    }
}
