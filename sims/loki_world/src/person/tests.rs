use super::*;

fn event(id: u64, state: SpeakingState, duration_s: f64) -> SpeakingEvent {
    SpeakingEvent {
        id,
        state,
        duration_s,
        text: format!("sentence {id}"),
        ..SpeakingEvent::default()
    }
}

/// Two sentences in a row: between the end of the first and the start of the queued second
/// the robot still has the floor (a person who spoke there was ignored by the dialog as
/// the robot's own echo, and had to repeat herself). A sentence whose end never comes (its
/// generator was killed) stops holding the floor once its audio would have ended.
#[test]
fn the_robot_keeps_the_floor_between_sentences_it_has_queued() {
    let t0 = Moment::from_duration(Duration::from_secs(1_000));
    let mut seen = Seen::default();
    assert!(!seen.robot_has_the_floor(t0));
    seen.on_speaking(&event(3, SpeakingState::Queued, 0.0), t0);
    seen.on_speaking(&event(3, SpeakingState::Started, 1.6), t0);
    seen.on_speaking(&event(4, SpeakingState::Queued, 0.0), t0);
    let t1 = t0 + Duration::from_millis(1600);
    seen.on_speaking(&event(3, SpeakingState::Finished, 1.6), t1);
    assert!(
        seen.robot_has_the_floor(t1),
        "the queued sentence 4 is next"
    );
    seen.on_speaking(&event(4, SpeakingState::Started, 1.25), t1);
    seen.on_speaking(
        &event(4, SpeakingState::Finished, 1.25),
        t1 + Duration::from_millis(1250),
    );
    assert!(!seen.robot_has_the_floor(t1 + Duration::from_millis(1250)));
    // Started and never finished: the floor is free 1 s after its audio's end.
    seen.on_speaking(&event(5, SpeakingState::Started, 2.0), t1);
    assert!(seen.robot_has_the_floor(t1 + Duration::from_millis(2900)));
    assert!(!seen.robot_has_the_floor(t1 + Duration::from_millis(3100)));
}

/// Told the robot cannot hear her, she waits until it says it can (a minute at most).
#[test]
fn she_waits_while_the_robot_cannot_hear_her() {
    let t0 = Moment::from_duration(Duration::from_secs(1_000));
    let mut seen = Seen::default();
    let mut e = event(7, SpeakingState::Started, 2.0);
    e.text = "I can't hear you for a moment. Please wait.".into();
    seen.on_speaking(&e, t0);
    seen.on_speaking(
        &event(7, SpeakingState::Finished, 2.0),
        t0 + Duration::from_secs(2),
    );
    assert!(seen.robot_has_the_floor(t0 + Duration::from_secs(30)));
    assert!(!seen.robot_has_the_floor(t0 + DEAF_AT_MOST + Duration::from_secs(1)));
    let mut e = event(8, SpeakingState::Started, 1.0);
    e.text = "I can hear you again.".into();
    seen.on_speaking(&e, t0 + Duration::from_secs(31));
    seen.on_speaking(
        &event(8, SpeakingState::Finished, 1.0),
        t0 + Duration::from_secs(32),
    );
    assert!(!seen.robot_has_the_floor(t0 + Duration::from_secs(32)));
}

#[test]
fn a_timing_is_one_json_object_with_its_action() {
    let t = Timing {
        step: 6,
        what: "ball event \"detected\"".into(),
        after_s: 1.235,
        action_step: 5,
        action: "says \"scan the ball\"".into(),
    };
    assert_eq!(
        serde_json::to_string(&t).unwrap(),
        r#"{"step":6,"what":"ball event \"detected\"","after_s":1.235,"action_step":5,"action":"says \"scan the ball\""}"#
    );
}

#[test]
fn rotation_by_a_quarter_turn_about_z() {
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let r = rotate(&[0.0, 0.0, h, h], &[1.0, 0.0, 0.0]);
    assert!((r[0]).abs() < 1e-12 && (r[1] - 1.0).abs() < 1e-12 && r[2].abs() < 1e-12);
}
