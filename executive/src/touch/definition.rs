//! The touch game's state tree and transitions, built on the [`crate::engine`].

use std::time::Duration;

use interfaces::msg::speech::Priority;

use super::{Act, Input, MACHINE, TouchCtx, say, state};
use crate::engine::{Builder, Definition, DefinitionError, Event};
use crate::settings::TouchSettings;

fn normal(text: &'static str) -> Act {
    Act::Say(text, Priority::Normal)
}
fn high(text: &'static str) -> Act {
    Act::Say(text, Priority::High)
}

pub(super) type Def = Definition<TouchCtx, Input, Act>;

fn seen(c: &TouchCtx, _: &Event<Input>) -> bool {
    c.ball_seen
}

fn silent(c: &TouchCtx, _: &Event<Input>) -> bool {
    !c.robot_talking
}

fn base_may_help(c: &TouchCtx, _: &Event<Input>) -> bool {
    !c.with_base && !c.settings.arm_with_base.is_empty()
}

/// The touch-the-ball machine for `settings` (see the module docs for the states).
pub fn definition(settings: &TouchSettings) -> Result<Def, DefinitionError> {
    use state::*;
    let mut b = Builder::<TouchCtx, Input, Act>::new(MACHINE);
    b.root_initial("game");
    b.compound(GAME, "waiting");
    // Looking at the person while listening to her; the ball takes the head when there is one
    // to look for.
    b.atomic(WAITING).entry(Act::GazeAtPerson);
    b.parallel(PLAYING).exit(Act::ClearTarget);
    b.compound(EYES, "idle");
    b.atomic(EYES_IDLE).entry(Act::GazeAtPerson);
    b.compound(SEARCHING, "looking")
        .entry(Act::SendTarget)
        .entry(Act::ScanFromStart)
        .entry(normal(say::LOOKING));
    b.atomic(LOOKING).entry(Act::ScanNext);
    b.atomic(HOLDING);
    b.atomic(TRACKING)
        .entry(Act::BallSeen(true))
        .entry(Act::GazeAtBall)
        .entry(normal(say::SEE_IT))
        .exit(Act::BallSeen(false));
    b.atomic(OUT_OF_SIGHT).entry(Act::CancelGaze);
    b.compound(ARM, "resting");
    b.atomic(RESTING);
    b.compound(REACHING, "moving").entry(Act::ReachBall);
    b.atomic(MOVING);
    b.atomic(TOUCHING);
    b.atomic(FOLLOWING).entry(normal(say::FOLLOWING));
    b.atomic(HOMING).entry(Act::HomeArm);
    b.final_state(FINISHED);

    // The whole game.
    for cmd in ["command:stop", "command:quit"] {
        b.on(GAME, cmd)
            .to(FINISHED)
            .action(Act::HomeArm)
            .action(Act::HeadAhead)
            .action(Act::Say(say::GOODBYE, Priority::Urgent))
            .action(Act::Finish);
    }
    b.on(GAME, "command:greet").action(normal(say::GREETING));
    b.on(GAME, "command:none")
        .action(normal(say::PLEASE_REPEAT));
    b.on(GAME, "command:other_game")
        .action(normal(say::NOT_THIS_GAME));
    // Explanations: in the arm region (one answer, however many regions are active).
    for s in [WAITING, ARM] {
        b.on(s, "command:touch_ball").action(normal(say::NOT_SEEN));
        b.on(s, "command:you_touched_it")
            .action(normal(say::NOT_TOUCHING));
    }

    // Waiting for the person.
    b.on(WAITING, "command:play")
        .to(PLAYING)
        .action(normal(say::PLAY_ACK));
    for cmd in ["command:scan_ball", "command:track_ball"] {
        b.on(WAITING, cmd).to(SEARCHING);
        b.on(EYES_IDLE, cmd).to(SEARCHING);
        b.on(SEARCHING, cmd).action(normal(say::ALREADY_LOOKING));
        b.on(TRACKING, cmd).action(normal(say::ALREADY_SEE_IT));
        b.on(OUT_OF_SIGHT, cmd).to(SEARCHING);
    }
    b.on(PLAYING, "command:play")
        .action(normal(say::ALREADY_PLAYING));

    // The eyes. The scan: on to the next point once the neck is there (or cannot get there) and
    // held still a moment; a neck that says nothing does not stop the scan.
    for st in ["gaze:reached", "gaze:unreachable", "gaze:failed"] {
        b.on(LOOKING, st).to(HOLDING);
    }
    b.after(
        LOOKING,
        Duration::from_secs_f64(settings.scan_move_timeout_s),
        "scan",
    )
    .to(LOOKING);
    b.after(
        HOLDING,
        Duration::from_secs_f64(settings.scan_dwell_s),
        "dwell",
    )
    .to(LOOKING);
    b.on(SEARCHING, "ball:detected").to(TRACKING);
    b.on(SEARCHING, "ball:detection_timed_out")
        .action(Act::SendTarget)
        .action(normal(say::CANNOT_FIND));
    b.on(TRACKING, "ball:out_of_view")
        .to(OUT_OF_SIGHT)
        .action(high(say::OUT_OF_SIGHT));
    b.on(TRACKING, "ball:lost")
        .to(SEARCHING)
        .action(high(say::LOST));
    b.on(TRACKING, "ball:detection_timed_out")
        .to(SEARCHING)
        .action(high(say::LOST));
    b.on(OUT_OF_SIGHT, "ball:lost")
        .to(SEARCHING)
        .action(high(say::LOST));
    b.on(OUT_OF_SIGHT, "ball:detection_timed_out")
        .to(SEARCHING)
        .action(high(say::LOST));
    b.on(OUT_OF_SIGHT, "ball:detected").to(TRACKING);
    // The tracker reported the ball at the border (say, while the head was still turning) but
    // kept it, and the stopped head sees it well inside the image: follow it again.
    b.on(OUT_OF_SIGHT, "ball:in_view").to(TRACKING);

    // The arm.
    b.on(RESTING, "command:touch_ball")
        .guard("ball seen", seen)
        .to(REACHING)
        .action(normal(say::GOING_TO_TOUCH));
    b.on(HOMING, "command:touch_ball")
        .guard("ball seen", seen)
        .to(REACHING)
        .action(normal(say::GOING_TO_TOUCH));
    b.after(HOMING, Duration::from_secs_f64(settings.homing_s), "homed")
        .to(RESTING);
    b.on(REACHING, "command:touch_ball")
        .guard("ball seen", seen)
        .to(REACHING)
        .action(normal(say::GOING_TO_TOUCH));
    b.on(MOVING, "reach:reached")
        .to(TOUCHING)
        .action(normal(say::TOUCHING));
    b.on(FOLLOWING, "reach:reached")
        .to(TOUCHING)
        .action(normal(say::TOUCHING));
    // The courtesy delay counts from the robot's last word: a person waits for the robot to
    // finish talking before she answers. The timer does not fire while the robot talks, and a
    // sentence begun or ended while touching enters the state again (its timer starts again).
    for ev in ["speech:started", "speech:ended"] {
        b.on(TOUCHING, ev).to(TOUCHING);
    }
    b.on(MOVING, "ball:moved").to(FOLLOWING);
    b.on(TOUCHING, "ball:moved").to(FOLLOWING);
    b.after(
        TOUCHING,
        Duration::from_secs_f64(settings.courtesy_delay_s),
        "courtesy",
    )
    .guard("the robot is silent", silent)
    .to(HOMING)
    .action(normal(say::COURTESY));
    b.on(REACHING, "command:you_touched_it")
        .to(HOMING)
        .action(normal(say::THANKS));
    // Too far for the arm alone: the base turns (and moves a little) and the arm reaches again;
    // too far for both, the robot says so.
    b.on(REACHING, "reach:unreachable")
        .guard("the base may help", base_may_help)
        .to(REACHING)
        .action(Act::UseBase)
        .action(normal(say::TURNING));
    b.on(REACHING, "reach:unreachable")
        .to(HOMING)
        .action(high(say::CANT_REACH));
    b.on(REACHING, "reach:failed")
        .to(HOMING)
        .action(high(say::ARM_FAILED));
    b.on(REACHING, "ball:lost").to(HOMING);
    b.build()
}
