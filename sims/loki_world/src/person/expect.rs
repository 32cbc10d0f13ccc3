//! Waiting for what the person expects of the robot: the checks of a scenario's `expect` step
//! against what she saw and the DR's poses, and the robot's questions she answers meanwhile.

use super::{PersonConfig, Seen, ball_event_name, lock, reach_name};
use crate::ball::{Ball, BallState, dist};
use crate::scenario::{Expect, Scenario};
use interfaces::msg::dr::TransformRequest;
use interfaces::{Bus, CallError, Moment, topics};
use std::sync::Mutex;
use std::time::Duration;

/// Figures measured while checking an expectation.
#[derive(Debug, Default, Clone, Copy)]
pub(super) struct Figures {
    pub(super) hand_to_ball_m: Option<f64>,
    pub(super) gaze_deg: Option<f64>,
}

impl Figures {
    pub(super) fn describe(&self) -> String {
        let mut s = String::new();
        if let Some(d) = self.hand_to_ball_m {
            s += &format!("; hand {:.1} cm from the ball's surface", d * 100.0);
        }
        if let Some(a) = self.gaze_deg {
            s += &format!("; gaze {a:.1} deg off the ball");
        }
        s
    }
}

/// What came of waiting for an expectation.
pub(super) enum Waited {
    /// It holds, with what was measured.
    Seen(Figures),
    /// The robot asks "Did you say ...?" about what she said last, and she has not answered it
    /// yet: she answers, and waits on.
    Asked,
    /// The time-out, with what was seen instead.
    Timeout(String),
}

/// Whether the robot, since `mark`, asked about `said` (her last words) more often than the
/// `answered` times she answered.
fn asked_about(s: &Seen, mark: Moment, said: &str, answered: usize) -> bool {
    let question = format!("did you say {}", said.to_lowercase());
    s.said
        .iter()
        .filter(|(t, x)| *t >= mark && x.contains(&question))
        .count()
        > answered
}

/// Wait for `e` until `deadline`. `question`: her last words and how many times she answered the
/// robot's question about them: asked again, she answers "yes" (a person who said it would),
/// unless the question is what she waits for.
#[allow(clippy::too_many_arguments)]
pub(super) async fn expect(
    bus: &Bus,
    cfg: &PersonConfig,
    sc: &Scenario,
    e: &Expect,
    mark: Moment,
    seen: &Mutex<Seen>,
    ball: &Mutex<Ball>,
    now_s: impl Fn() -> f64,
    deadline: Moment,
    question: Option<(&str, usize)>,
    shutdown: &mut interfaces::node::Shutdown,
) -> anyhow::Result<Waited> {
    let clock = bus.clock();
    let radius = sc.ball.diameter_m / 2.0;
    let mut last_geometry = String::new();
    loop {
        let mut figures = Figures::default();
        let mut ok = {
            let s = lock(seen);
            let since = |t: &Moment| *t >= mark;
            let said = e.robot_said.as_ref().is_none_or(|w| {
                let w = w.to_lowercase();
                s.said.iter().any(|(t, x)| since(t) && x.contains(&w))
            });
            let state = e.state.as_ref().is_none_or(|w| {
                s.entered
                    .iter()
                    .any(|(t, x)| since(t) && x.contains(w.as_str()))
                    || s.active.iter().any(|x| x.contains(w.as_str()))
            });
            let reach = e.reach.as_ref().is_none_or(|w| {
                s.reach
                    .iter()
                    .any(|(t, part, st)| since(t) && part != "neck" && reach_name(*st) == w)
            });
            let ev = e.ball_event.as_ref().is_none_or(|w| {
                s.ball_events
                    .iter()
                    .any(|(t, k)| since(t) && ball_event_name(*k) == w)
            });
            said && state && reach && ev
        };
        let b: BallState = lock(ball).at(now_s());
        if let Some(limit) = e.hand_to_ball_m {
            match frame_in_world(bus, &cfg.hand_frame).await {
                Ok((p, _)) => {
                    let d = dist(&p, &b.position_m) - radius;
                    figures.hand_to_ball_m = Some(d);
                    last_geometry = format!(
                        "the hand is {:.1} cm from the ball's surface (hand at ({:.3}, {:.3}, {:.3}) m)",
                        d * 100.0,
                        p[0],
                        p[1],
                        p[2]
                    );
                    ok &= d <= limit;
                }
                Err(err) => {
                    last_geometry = format!("no hand pose from the DR: {err}");
                    ok = false;
                }
            }
        }
        if let Some(limit) = e.gaze_on_ball_deg {
            match frame_in_world(bus, &cfg.camera_frame).await {
                Ok((p, q)) => {
                    let axis = rotate(&q, &[0.0, 0.0, 1.0]);
                    let to = [
                        b.position_m[0] - p[0],
                        b.position_m[1] - p[1],
                        b.position_m[2] - p[2],
                    ];
                    let n = dist(&to, &[0.0; 3]).max(1e-9);
                    let cos = (axis[0] * to[0] + axis[1] * to[1] + axis[2] * to[2]) / n;
                    let a = cos.clamp(-1.0, 1.0).acos().to_degrees();
                    figures.gaze_deg = Some(a);
                    last_geometry = format!("the gaze is {a:.1} deg off the ball");
                    ok &= a <= limit;
                }
                Err(err) => {
                    last_geometry = format!("no camera pose from the DR: {err}");
                    ok = false;
                }
            }
        }
        if ok {
            return Ok(Waited::Seen(figures));
        }
        if let Some((said, answered)) = question
            && asked_about(&lock(seen), mark, said, answered)
        {
            return Ok(Waited::Asked);
        }
        if clock.now() >= deadline {
            let s = lock(seen);
            let said: Vec<&str> = s
                .said
                .iter()
                .filter(|(t, _)| *t >= mark)
                .map(|(_, x)| x.as_str())
                .collect();
            let reach: Vec<String> = s
                .reach
                .iter()
                .filter(|(t, p, _)| *t >= mark && p != "neck")
                .map(|(_, p, st)| format!("{p} {}", reach_name(*st)))
                .collect();
            let events: Vec<&str> = s
                .ball_events
                .iter()
                .filter(|(t, _)| *t >= mark)
                .map(|(_, k)| ball_event_name(*k))
                .collect();
            return Ok(Waited::Timeout(format!(
                "seen instead: robot said {said:?}; active states {:?}; arm {reach:?}; ball events {events:?}{}{last_geometry}",
                s.active,
                if last_geometry.is_empty() { "" } else { "; " }
            )));
        }
        tokio::select! {
            _ = clock.sleep(Duration::from_millis(100)) => {}
            _ = shutdown.wait() => anyhow::bail!("stopped while waiting for {}", e.describe()),
        }
    }
}

/// `world_T_frame` from the DR: translation (m) and rotation `[x, y, z, w]`.
async fn frame_in_world(bus: &Bus, frame: &str) -> Result<([f64; 3], [f64; 4]), CallError> {
    let req = TransformRequest {
        target: "world".into(),
        source: frame.into(),
        ..TransformRequest::default()
    };
    let rep = bus
        .call(&topics::DR_TRANSFORM, &req, Duration::from_millis(500))
        .await?;
    Ok((rep.transform.translation_m, rep.transform.rotation_xyzw))
}

/// Rotate `v` by the unit quaternion `q = [x, y, z, w]`.
pub fn rotate(q: &[f64; 4], v: &[f64; 3]) -> [f64; 3] {
    let [x, y, z, w] = *q;
    // v' = v + 2 w (u x v) + 2 u x (u x v), u = (x, y, z)
    let u = [x, y, z];
    let cross = |a: &[f64; 3], b: &[f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let uv = cross(&u, v);
    let uuv = cross(&u, &uv);
    [
        v[0] + 2.0 * (w * uv[0] + uuv[0]),
        v[1] + 2.0 * (w * uv[1] + uuv[1]),
        v[2] + 2.0 * (w * uv[2] + uuv[2]),
    ]
}
