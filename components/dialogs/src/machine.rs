//! The dialog of seed 001 Fig. 5 as a pure state machine: what to do with each recognized
//! utterance given its confidence, when to ask "Did you say ...?", and what a yes, a no or
//! silence does. Time is passed in (seconds on any monotonic clock); nothing here reads a clock.
//!
//! With thresholds `low ≤ high` on the recognizer's confidence in [0, 1]:
//!
//! - **Idle**, a command heard with confidence ≥ `high`: published at once.
//! - **Idle**, `low ≤` confidence `< high`: the robot asks "Did you say <phrase>?" and waits
//!   (**Confirming**) for a yes or a no, by voice or from the panel, for `answer_timeout_s`.
//!   Yes publishes the command (marked confirmed); no drops it and says so; the time-out drops it
//!   and says so.
//! - confidence `< low`, or out of grammar: ignored and counted; after `repeat_after` such
//!   utterances within `repeat_window_s` the robot asks to repeat.
//! - **Confirming**, a new command with confidence ≥ `high` replaces the question (published at
//!   once); one between the thresholds replaces the question with a new one.
//! - A yes or a no with no question pending is ignored (counted).
//! - Utterances heard while the robot speaks, or within `echo_guard_s` after, are ignored: they
//!   are most likely the robot hearing itself.
//! - **Barge-in** (`barge_in`, for a microphone whose signal has the robot's voice taken out by
//!   an echo canceller): a command heard over the robot with confidence ≥ `high` is taken. The
//!   robot is silenced first ([`Action::Hush`]), then the command is handled as above. What the
//!   canceller lets through of the robot's voice is not taken for the player's: the utterance
//!   must be one the recognizer heard as sustained speech ([`Dialog::speech_started`]; the
//!   canceller's leaks while it adapts are short bursts), and words that the robot is saying, or
//!   said within `echo_guard_s`, are still ignored ("I'm going to touch the ball" contains a
//!   command). Anything less sure is ignored, as without barge-in.

use interfaces::msg::command::{Command, Game};
use interfaces::msg::speech::Priority;
use serde::{Deserialize, Serialize};

/// Thresholds and times (s).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DialogConfig {
    pub high: f64,
    pub low: f64,
    pub answer_timeout_s: f64,
    pub repeat_after: u32,
    pub repeat_window_s: f64,
    pub echo_guard_s: f64,
    pub barge_in: bool,
}

impl Default for DialogConfig {
    fn default() -> Self {
        Self {
            high: 0.7,
            low: 0.3,
            answer_timeout_s: 8.0,
            repeat_after: 2,
            repeat_window_s: 15.0,
            echo_guard_s: 0.5,
            barge_in: false,
        }
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ConfigError {
    #[error("thresholds must satisfy 0 <= low <= high <= 1 (low {low}, high {high})")]
    Thresholds { low: f64, high: f64 },
    #[error("answer_timeout_s must be > 0 (got {0})")]
    Timeout(f64),
}

impl DialogConfig {
    pub fn validate(&self) -> Result<(), ConfigError> {
        if !(0.0..=1.0).contains(&self.low)
            || !(0.0..=1.0).contains(&self.high)
            || self.low > self.high
        {
            return Err(ConfigError::Thresholds {
                low: self.low,
                high: self.high,
            });
        }
        if self.answer_timeout_s.is_nan() || self.answer_timeout_s <= 0.0 {
            return Err(ConfigError::Timeout(self.answer_timeout_s));
        }
        Ok(())
    }
}

/// What the recognizer heard (the fields of `speech/utterance` the dialog uses).
#[derive(Debug, Clone, PartialEq)]
pub struct Heard {
    pub game: Game,
    pub text: String,
    pub confidence: f64,
    pub command: Command,
    /// When the words were heard (the utterance's stamp): the command it becomes keeps it, so
    /// the Executive knows a command sent again after a restart.
    pub stamp_ns: i64,
    /// Where the utterance starts on the recognizer's stream (s).
    pub stream_start_s: f64,
    /// When its words ended, on the dialog's time line (from the utterance's stamp, the audio's
    /// time): earlier than the arrival when a restarted recognizer caught up on them. `None`:
    /// at its arrival.
    pub said_s: Option<f64>,
}

/// A command the dialog lets through.
#[derive(Debug, Clone, PartialEq)]
pub struct Accepted {
    pub game: Game,
    pub command: Command,
    pub text: String,
    pub confidence: f64,
    pub confirmed: bool,
    /// When the command's words were heard ([`Heard::stamp_ns`]).
    pub stamp_ns: i64,
}

/// Why an utterance was ignored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IgnoreReason {
    OutOfGrammar,
    LowConfidence,
    AnswerWithoutQuestion,
    RobotSpeaking,
}

/// What the component must do.
#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    Publish(Accepted),
    Say {
        text: String,
        priority: Priority,
    },
    Ignored(IgnoreReason),
    /// Silence the robot now: the player talked over it (barge-in).
    Hush,
    /// A pending question ended without a command (no, time-out, superseded).
    Dropped(Command),
}

#[derive(Debug, Clone, PartialEq)]
enum State {
    Idle,
    Confirming { pending: Heard, deadline_s: f64 },
}

/// The dialog.
#[derive(Debug)]
pub struct Dialog {
    cfg: DialogConfig,
    state: State,
    /// Times of recent low-confidence utterances.
    misses: Vec<f64>,
    speaking: bool,
    /// When the robot's current sentence ends at the latest (its audio's duration and a margin
    /// after it started): a speech generator that dies mid-sentence never says it stopped, and
    /// the dialog must not stay deaf.
    speaking_until_s: f64,
    quiet_since_s: f64,
    /// The words of the robot's sentences since it was last quiet for `echo_guard_s`.
    robot_words: Vec<Vec<String>>,
    /// When the robot's current talk (its sentences since it was last quiet for
    /// `echo_guard_s`) began, and when it had been quiet since before it.
    talk_began: Option<(f64, f64)>,
    /// Where the last utterances the recognizer heard as sustained speech start (s on its
    /// stream), newest last.
    sustained: std::collections::VecDeque<f64>,
}

/// Words the grammars allow around a command ("robot, please stop").
const FILLERS: &[&str] = &["robot", "please"];

/// Lowercase words, without punctuation ("I'm going." -> ["i'm", "going"]).
fn words(text: &str) -> Vec<String> {
    text.split(|c: char| !(c.is_alphanumeric() || c == '\''))
        .filter(|w| !w.is_empty())
        .map(str::to_lowercase)
        .collect()
}

/// How long after its audio's end a sentence still counts as spoken (the generator's report of
/// the end is late by its audio buffer), s.
pub const SPEAKING_SLACK_S: f64 = 1.0;
/// How long a sentence of unknown duration counts as spoken without its end being heard, s.
pub const SPEAKING_MAX_S: f64 = 30.0;

impl Dialog {
    pub fn new(cfg: DialogConfig) -> Result<Self, ConfigError> {
        cfg.validate()?;
        Ok(Self {
            cfg,
            state: State::Idle,
            misses: Vec::new(),
            speaking: false,
            speaking_until_s: f64::NEG_INFINITY,
            quiet_since_s: f64::NEG_INFINITY,
            robot_words: Vec::new(),
            talk_began: None,
            sustained: Default::default(),
        })
    }

    /// The robot started saying `text`, `duration_s` seconds of audio (0: unknown), at `now_s`.
    pub fn robot_started_speaking(&mut self, now_s: f64, duration_s: f64, text: &str) {
        if !self.robot_heard_at(now_s) {
            self.robot_words.clear();
            self.talk_began = Some((now_s, self.quiet_since_s));
        }
        self.robot_words.push(words(text));
        let d = if duration_s.is_finite() && duration_s > 0.0 {
            duration_s.min(SPEAKING_MAX_S) + SPEAKING_SLACK_S
        } else {
            SPEAKING_MAX_S
        };
        self.speaking = true;
        self.speaking_until_s = now_s + d;
    }

    /// Whether the robot speaks at `now_s`: until it says it stopped, or its sentence's time is
    /// up (then it is taken as stopped at that time).
    fn speaking_at(&mut self, now_s: f64) -> bool {
        if self.speaking && now_s > self.speaking_until_s {
            let until = self.speaking_until_s;
            self.robot_speaking(until, false);
        }
        self.speaking
    }

    /// The recognizer heard sustained speech start at `stream_s` on its stream (not a click, a
    /// cough, or what an echo canceller lets through of the robot): only such an utterance may
    /// be taken over the robot.
    pub fn speech_started(&mut self, stream_s: f64) {
        if self.sustained.len() == 16 {
            self.sustained.pop_front();
        }
        self.sustained.push_back(stream_s);
    }

    /// Whether what is heard at `now_s` may be the robot itself: it speaks, or stopped less than
    /// `echo_guard_s` ago.
    fn robot_heard_at(&mut self, now_s: f64) -> bool {
        self.speaking_at(now_s) || now_s - self.quiet_since_s < self.cfg.echo_guard_s
    }

    /// Whether words that ended at `said_s` may be the robot itself. Words said before the
    /// robot's current talk began (a restarted recognizer catching up on them) are judged by
    /// the quiet before that talk, not by the talk.
    fn robot_heard_when(&mut self, said_s: f64) -> bool {
        match self.talk_began {
            Some((began_s, quiet_before_s)) if said_s < began_s => {
                said_s - quiet_before_s < self.cfg.echo_guard_s
            }
            _ => self.robot_heard_at(said_s),
        }
    }

    /// Whether `text` is words of what the robot is saying or just said.
    fn robot_said(&self, text: &str) -> bool {
        let heard: Vec<String> = words(text)
            .into_iter()
            .filter(|w| !FILLERS.contains(&w.as_str()))
            .collect();
        !heard.is_empty()
            && self
                .robot_words
                .iter()
                .any(|s| s.windows(heard.len()).any(|w| w == heard.as_slice()))
    }

    /// The command awaiting a yes or no, if any.
    pub fn pending(&self) -> Option<Command> {
        match &self.state {
            State::Idle => None,
            State::Confirming { pending, .. } => Some(pending.command),
        }
    }

    /// The robot started (`true`) or stopped speaking.
    pub fn robot_speaking(&mut self, now_s: f64, speaking: bool) {
        if speaking && !self.speaking {
            self.speaking_until_s = now_s + SPEAKING_MAX_S;
        }
        if self.speaking && !speaking {
            self.quiet_since_s = now_s;
            // The person can only answer once the question is over.
            if let State::Confirming { deadline_s, .. } = &mut self.state {
                *deadline_s = deadline_s.max(now_s + self.cfg.answer_timeout_s);
            }
        }
        self.speaking = speaking;
    }

    fn ask(&mut self, now_s: f64, heard: Heard, out: &mut Vec<Action>) {
        out.push(Action::Say {
            text: format!("Did you say {}?", heard.command.phrase()),
            priority: Priority::High,
        });
        self.state = State::Confirming {
            pending: heard,
            deadline_s: now_s + self.cfg.answer_timeout_s,
        };
    }

    fn miss(&mut self, now_s: f64, reason: IgnoreReason, out: &mut Vec<Action>) {
        out.push(Action::Ignored(reason));
        let window = self.cfg.repeat_window_s;
        self.misses.retain(|t| now_s - t <= window);
        self.misses.push(now_s);
        if self.cfg.repeat_after > 0 && self.misses.len() >= self.cfg.repeat_after as usize {
            self.misses.clear();
            out.push(Action::Say {
                text: "Sorry, I did not understand. Please repeat.".into(),
                priority: Priority::Normal,
            });
        }
    }

    fn answer(&mut self, yes: bool, out: &mut Vec<Action>) {
        let State::Confirming { pending, .. } = std::mem::replace(&mut self.state, State::Idle)
        else {
            out.push(Action::Ignored(IgnoreReason::AnswerWithoutQuestion));
            return;
        };
        if yes {
            out.push(Action::Say {
                text: format!("OK, {}.", pending.command.phrase()),
                priority: Priority::Normal,
            });
            out.push(Action::Publish(Accepted {
                game: pending.game,
                command: pending.command,
                text: pending.text,
                confidence: pending.confidence,
                confirmed: true,
                stamp_ns: pending.stamp_ns,
            }));
        } else {
            out.push(Action::Dropped(pending.command));
            out.push(Action::Say {
                text: "Sorry. Please say the command again.".into(),
                priority: Priority::Normal,
            });
        }
    }

    /// A recognized utterance at `now_s`.
    pub fn heard(&mut self, now_s: f64, h: Heard) -> Vec<Action> {
        let mut out = Vec::new();
        if self.robot_heard_when(h.said_s.unwrap_or(now_s).min(now_s)) {
            let barge_in = self.cfg.barge_in
                && h.command != Command::None
                && h.confidence >= self.cfg.high
                && self
                    .sustained
                    .iter()
                    .any(|&s| (s - h.stream_start_s).abs() < 0.011)
                && !self.robot_said(&h.text);
            if !barge_in {
                out.push(Action::Ignored(IgnoreReason::RobotSpeaking));
                return out;
            }
            if self.speaking {
                out.push(Action::Hush);
            }
        }
        if h.command == Command::None {
            self.miss(now_s, IgnoreReason::OutOfGrammar, &mut out);
            return out;
        }
        if h.confidence < self.cfg.low {
            self.miss(now_s, IgnoreReason::LowConfidence, &mut out);
            return out;
        }
        self.misses.clear();
        if h.command.is_answer() {
            self.answer(h.command == Command::Yes, &mut out);
            return out;
        }
        if let State::Confirming { pending, .. } = &self.state {
            out.push(Action::Dropped(pending.command));
            self.state = State::Idle;
        }
        if h.confidence >= self.cfg.high {
            out.push(Action::Publish(Accepted {
                game: h.game,
                command: h.command,
                text: h.text,
                confidence: h.confidence,
                confirmed: false,
                stamp_ns: h.stamp_ns,
            }));
        } else {
            self.ask(now_s, h, &mut out);
        }
        out
    }

    /// A yes/no from the command panel.
    pub fn panel_answer(&mut self, _now_s: f64, yes: bool) -> Vec<Action> {
        let mut out = Vec::new();
        self.answer(yes, &mut out);
        out
    }

    /// Time passes: a question past its deadline is dropped.
    pub fn tick(&mut self, now_s: f64) -> Vec<Action> {
        let mut out = Vec::new();
        self.speaking_at(now_s);
        if let State::Confirming {
            pending,
            deadline_s,
        } = &self.state
            && now_s >= *deadline_s
        {
            let phrase = pending.command.phrase();
            out.push(Action::Dropped(pending.command));
            out.push(Action::Say {
                text: format!("No answer. I ignore {phrase}."),
                priority: Priority::Normal,
            });
            self.state = State::Idle;
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn heard(command: Command, confidence: f64) -> Heard {
        Heard {
            game: Game::Touch,
            text: command.phrase().to_string(),
            confidence,
            command,
            stamp_ns: 0,
            stream_start_s: 0.0,
            said_s: None,
        }
    }
    fn dialog() -> Dialog {
        Dialog::new(DialogConfig::default()).unwrap()
    }
    fn published(a: &[Action]) -> Vec<(Command, bool)> {
        a.iter()
            .filter_map(|x| match x {
                Action::Publish(p) => Some((p.command, p.confirmed)),
                _ => None,
            })
            .collect()
    }
    fn said(a: &[Action]) -> Vec<String> {
        a.iter()
            .filter_map(|x| match x {
                Action::Say { text, .. } => Some(text.clone()),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn sure_commands_go_straight_through() {
        let mut d = dialog();
        let a = d.heard(0.0, heard(Command::TouchBall, 0.9));
        assert_eq!(published(&a), vec![(Command::TouchBall, false)]);
        assert!(said(&a).is_empty());
        assert_eq!(d.pending(), None);
        // Exactly at the high threshold counts as sure.
        assert_eq!(published(&d.heard(1.0, heard(Command::Stop, 0.7))).len(), 1);
    }

    #[test]
    fn unsure_command_confirmed_by_voice_yes() {
        let mut d = dialog();
        let a = d.heard(0.0, heard(Command::TrackBall, 0.5));
        assert!(published(&a).is_empty());
        assert_eq!(said(&a), vec!["Did you say track the ball?"]);
        assert_eq!(d.pending(), Some(Command::TrackBall));
        let a = d.heard(3.0, heard(Command::Yes, 0.4));
        assert_eq!(published(&a), vec![(Command::TrackBall, true)]);
        assert_eq!(d.pending(), None);
    }

    #[test]
    fn unsure_command_rejected_by_no_or_the_panel() {
        let mut d = dialog();
        d.heard(0.0, heard(Command::ScanBall, 0.5));
        let a = d.heard(2.0, heard(Command::No, 0.8));
        assert!(published(&a).is_empty());
        assert!(a.contains(&Action::Dropped(Command::ScanBall)));
        assert!(said(&a)[0].contains("again"));
        // Panel answers work the same.
        d.heard(10.0, heard(Command::ScanBall, 0.5));
        let a = d.panel_answer(11.0, true);
        assert_eq!(published(&a), vec![(Command::ScanBall, true)]);
        d.heard(20.0, heard(Command::Quit, 0.5));
        let a = d.panel_answer(21.0, false);
        assert_eq!(a[0], Action::Dropped(Command::Quit));
    }

    #[test]
    fn unanswered_question_times_out_and_says_so() {
        let mut d = dialog();
        d.heard(0.0, heard(Command::TouchBall, 0.5));
        assert!(d.tick(7.9).is_empty());
        let a = d.tick(8.0);
        assert_eq!(a[0], Action::Dropped(Command::TouchBall));
        assert_eq!(said(&a), vec!["No answer. I ignore touch the ball."]);
        assert_eq!(d.pending(), None);
        // A late yes has no question left.
        assert_eq!(
            d.heard(9.0, heard(Command::Yes, 0.9)),
            vec![Action::Ignored(IgnoreReason::AnswerWithoutQuestion)]
        );
        assert!(d.tick(100.0).is_empty());
    }

    #[test]
    fn the_time_out_runs_from_the_end_of_the_question() {
        let mut d = dialog();
        d.heard(0.0, heard(Command::TouchBall, 0.5));
        d.robot_speaking(0.1, true);
        d.robot_speaking(2.0, false);
        assert!(d.tick(9.0).is_empty(), "deadline moved to 2 + 8 s");
        assert_eq!(d.tick(10.0)[0], Action::Dropped(Command::TouchBall));
    }

    #[test]
    fn low_confidence_and_out_of_grammar_are_ignored_then_a_repeat_is_asked() {
        let mut d = dialog();
        let a = d.heard(0.0, heard(Command::TouchBall, 0.1));
        assert_eq!(a, vec![Action::Ignored(IgnoreReason::LowConfidence)]);
        let a = d.heard(3.0, heard(Command::None, 0.9));
        assert_eq!(a[0], Action::Ignored(IgnoreReason::OutOfGrammar));
        assert_eq!(
            said(&a),
            vec!["Sorry, I did not understand. Please repeat."]
        );
        // Misses far apart do not add up.
        let mut d = dialog();
        d.heard(0.0, heard(Command::TouchBall, 0.1));
        let a = d.heard(20.0, heard(Command::TouchBall, 0.1));
        assert!(said(&a).is_empty());
        // A good command in between resets the count.
        d.heard(21.0, heard(Command::Stop, 0.9));
        assert!(said(&d.heard(22.0, heard(Command::Stop, 0.1))).is_empty());
        // A low-confidence yes does not answer the question.
        let mut d = dialog();
        d.heard(0.0, heard(Command::TouchBall, 0.5));
        let a = d.heard(1.0, heard(Command::Yes, 0.1));
        assert!(published(&a).is_empty());
        assert_eq!(d.pending(), Some(Command::TouchBall));
    }

    #[test]
    fn a_new_command_replaces_the_question() {
        let mut d = dialog();
        d.heard(0.0, heard(Command::TouchBall, 0.5));
        let a = d.heard(1.0, heard(Command::Stop, 0.95));
        assert_eq!(a[0], Action::Dropped(Command::TouchBall));
        assert_eq!(published(&a), vec![(Command::Stop, false)]);
        assert_eq!(d.pending(), None);
        d.heard(2.0, heard(Command::TouchBall, 0.5));
        let a = d.heard(3.0, heard(Command::TrackBall, 0.5));
        assert_eq!(a[0], Action::Dropped(Command::TouchBall));
        assert_eq!(said(&a), vec!["Did you say track the ball?"]);
        assert_eq!(d.pending(), Some(Command::TrackBall));
    }

    #[test]
    fn what_is_heard_while_the_robot_speaks_is_ignored() {
        let mut d = dialog();
        d.robot_speaking(0.0, true);
        assert_eq!(
            d.heard(0.5, heard(Command::TouchBall, 0.9)),
            vec![Action::Ignored(IgnoreReason::RobotSpeaking)]
        );
        d.robot_speaking(1.0, false);
        assert_eq!(
            d.heard(1.3, heard(Command::TouchBall, 0.9)),
            vec![Action::Ignored(IgnoreReason::RobotSpeaking)]
        );
        assert_eq!(
            published(&d.heard(1.6, heard(Command::TouchBall, 0.9))).len(),
            1
        );
    }

    #[test]
    fn with_barge_in_a_sure_command_over_the_robot_silences_it_and_is_taken() {
        let mut d = Dialog::new(DialogConfig {
            barge_in: true,
            ..DialogConfig::default()
        })
        .unwrap();
        d.robot_started_speaking(0.0, 4.0, "Great, let's play! Show me the ball.");
        // A short burst heard as a sure "no" (what the echo canceller lets through while it
        // adapts): not sustained speech, ignored.
        let burst = Heard {
            stream_start_s: 12.0,
            said_s: None,
            ..heard(Command::No, 0.8)
        };
        assert_eq!(
            d.heard(1.0, burst),
            vec![Action::Ignored(IgnoreReason::RobotSpeaking)]
        );
        // The player says "stop" over the robot: sustained speech.
        d.speech_started(13.0);
        let stop = Heard {
            stream_start_s: 13.0,
            said_s: None,
            ..heard(Command::Stop, 0.9)
        };
        let a = d.heard(1.5, stop);
        assert_eq!(a[0], Action::Hush, "{a:?}");
        assert_eq!(published(&a), vec![(Command::Stop, false)]);
        d.speech_started(0.0);
        // Less sure: ignored, never asked about over the robot's voice.
        d.robot_started_speaking(10.0, 4.0, "I'm looking for the ball.");
        assert_eq!(
            d.heard(11.0, heard(Command::TrackBall, 0.5)),
            vec![Action::Ignored(IgnoreReason::RobotSpeaking)]
        );
        // The robot's own words, however sure, are its echo: while it says them and within the
        // echo guard after.
        d.robot_started_speaking(20.0, 2.0, "I'm going to touch the ball.");
        let robot = |c: f64| Heard {
            text: "robot touch the ball".into(),
            ..heard(Command::TouchBall, c)
        };
        assert_eq!(
            d.heard(21.0, robot(0.95)),
            vec![Action::Ignored(IgnoreReason::RobotSpeaking)]
        );
        d.robot_speaking(22.0, false);
        assert_eq!(
            d.heard(22.3, robot(0.95)),
            vec![Action::Ignored(IgnoreReason::RobotSpeaking)]
        );
        // Just after it stopped, a sure command of other words is taken without a hush.
        let a = d.heard(22.4, heard(Command::ScanBall, 0.9));
        assert_eq!(published(&a), vec![(Command::ScanBall, false)]);
        assert!(!a.contains(&Action::Hush));
        // Once the robot was quiet for the guard, its old words are the player's again.
        assert_eq!(published(&d.heard(30.0, robot(0.95))).len(), 1);
        // Without barge-in, the same "stop" over the robot is ignored.
        let mut d = dialog();
        d.robot_started_speaking(0.0, 4.0, "Great, let's play!");
        assert_eq!(
            d.heard(1.5, heard(Command::Stop, 0.99)),
            vec![Action::Ignored(IgnoreReason::RobotSpeaking)]
        );
    }

    #[test]
    fn bad_thresholds_are_refused_and_config_reads_from_toml() {
        let bad = DialogConfig {
            low: 0.8,
            high: 0.5,
            ..DialogConfig::default()
        };
        assert!(matches!(
            Dialog::new(bad),
            Err(ConfigError::Thresholds { .. })
        ));
        let bad = DialogConfig {
            answer_timeout_s: 0.0,
            ..DialogConfig::default()
        };
        assert!(Dialog::new(bad).is_err());
        let c: DialogConfig = toml::from_str("high = 0.8\nlow = 0.2\n").unwrap();
        assert_eq!((c.high, c.low, c.answer_timeout_s), (0.8, 0.2, 8.0));
        assert!(toml::from_str::<DialogConfig>("hgh = 0.8").is_err());
    }

    #[test]
    fn a_sentence_whose_end_is_never_heard_stops_counting_after_its_duration() {
        // The speech generator died mid-sentence: no Finished ever comes. The dialog hears the
        // person again once the sentence's audio would have ended (and the echo guard after).
        let mut d = Dialog::new(DialogConfig::default()).unwrap();
        d.robot_started_speaking(10.0, 1.6, "I see the ball.");
        let touch = || Heard {
            game: Game::Touch,
            text: "touch the ball".into(),
            confidence: 0.95,
            command: Command::TouchBall,
            stamp_ns: 0,
            stream_start_s: 0.0,
            said_s: None,
        };
        assert_eq!(
            d.heard(11.0, touch()),
            vec![Action::Ignored(IgnoreReason::RobotSpeaking)]
        );
        d.tick(12.7);
        let out = d.heard(13.5, touch());
        assert!(
            out.iter()
                .any(|a| matches!(a, Action::Publish(c) if c.command == Command::TouchBall)),
            "{out:?}"
        );
        // A start with no duration counts for SPEAKING_MAX_S at most.
        d.robot_started_speaking(20.0, 0.0, "Hello.");
        assert_eq!(
            d.heard(20.0 + SPEAKING_MAX_S - 1.0, touch()),
            vec![Action::Ignored(IgnoreReason::RobotSpeaking)]
        );
        let out = d.heard(20.0 + SPEAKING_MAX_S + 1.0, touch());
        assert!(
            out.iter().any(|a| matches!(a, Action::Publish(_))),
            "{out:?}"
        );
    }

    #[test]
    fn words_said_before_the_robot_began_to_talk_are_taken_when_they_arrive_late() {
        let mut d = dialog();
        // "let's play" ended at 10 s; the recognizer, restarted, caught up on it and hands it on
        // at 12.5 s, while the robot says it can hear again (from 12 s).
        d.robot_started_speaking(12.0, 1.5, "I can hear you again.");
        let late = Heard {
            said_s: Some(10.0),
            ..heard(Command::Play, 0.95)
        };
        assert_eq!(
            published(&d.heard(12.5, late)),
            vec![(Command::Play, false)]
        );
        // Words that ended while the robot talks may be its echo: ignored as before.
        let during = Heard {
            said_s: Some(12.4),
            ..heard(Command::ScanBall, 0.95)
        };
        assert_eq!(
            d.heard(12.6, during),
            vec![Action::Ignored(IgnoreReason::RobotSpeaking)]
        );
        // So are words that ended within the echo guard after the talk before this one.
        d.robot_speaking(14.0, false);
        d.robot_started_speaking(20.0, 1.0, "I see the ball.");
        let echo = Heard {
            said_s: Some(14.1),
            ..heard(Command::ScanBall, 0.95)
        };
        assert_eq!(
            d.heard(20.5, echo),
            vec![Action::Ignored(IgnoreReason::RobotSpeaking)]
        );
    }
}
