//! The game command catalog: every command a person can give either game, by voice or from the
//! command panel, with its canonical English phrase and the other phrasings the speech grammars
//! accept.
//!
//! - **Games**: [`Game::Touch`] is Loki's "touch the ball" (seed 001 §V), [`Game::Coach`] the Nao
//!   coach game (seed 000 §4.3). `Stop`, `Yes` and `No` belong to both.
//! - **Phrases** are lowercase words separated by single spaces, with no punctuation: exactly the
//!   words a recognizer outputs. [`Command::from_phrase`] maps a transcription back to its command
//!   after normalising case and spacing and dropping the politeness words of [`FILLER_WORDS`].
//! - `Yes` and `No` are the answers of the dialog's confirmation step, not game actions.

use crate::header::Header;
use serde::{Deserialize, Serialize};

/// Which game a command belongs to.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Game {
    /// Loki's touch-the-ball game.
    #[default]
    Touch,
    /// The Nao coach game.
    Coach,
}

impl Game {
    pub const ALL: [Game; 2] = [Game::Touch, Game::Coach];
    /// Lowercase name (`touch`, `coach`), as used in grammar file names and flags.
    pub fn name(self) -> &'static str {
        match self {
            Game::Touch => "touch",
            Game::Coach => "coach",
        }
    }
    pub fn from_name(s: &str) -> Option<Game> {
        Game::ALL.into_iter().find(|g| g.name() == s)
    }
}

/// A command of either game. `None` is "no command" (an out-of-grammar utterance, a default).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Command {
    #[default]
    None,
    // touch the ball
    Greet,
    Play,
    TrackBall,
    ScanBall,
    TouchBall,
    YouTouchedIt,
    Quit,
    // both games
    Stop,
    Yes,
    No,
    // coach
    GoToBallAndDribble,
    Pass,
    Kick,
    ClearBall,
    LookLeft,
    LookRight,
    LookAtBall,
    GoToPosition,
    SearchBall,
    Turn,
    AskForBall,
}

/// Words a speaker may add around a command that carry no meaning ("robot, please kick the ball").
pub const FILLER_WORDS: &[&str] = &["please", "robot", "now"];

impl Command {
    /// Every command except `None`.
    pub const ALL: [Command; 21] = [
        Command::Greet,
        Command::Play,
        Command::TrackBall,
        Command::ScanBall,
        Command::TouchBall,
        Command::YouTouchedIt,
        Command::Quit,
        Command::Stop,
        Command::Yes,
        Command::No,
        Command::GoToBallAndDribble,
        Command::Pass,
        Command::Kick,
        Command::ClearBall,
        Command::LookLeft,
        Command::LookRight,
        Command::LookAtBall,
        Command::GoToPosition,
        Command::SearchBall,
        Command::Turn,
        Command::AskForBall,
    ];

    /// The phrases of this command, canonical first (lowercase, single spaces, no filler words).
    pub fn phrases(self) -> &'static [&'static str] {
        match self {
            Command::None => &[],
            Command::Greet => &["hello", "hi"],
            Command::Play => &["let's play", "start the game"],
            Command::TrackBall => &["track the ball", "follow the ball"],
            Command::ScanBall => &["scan the ball", "find the ball"],
            Command::TouchBall => &["touch the ball", "touch it"],
            Command::YouTouchedIt => &["you touched it", "well done"],
            Command::Quit => &["quit the game", "game over"],
            Command::Stop => &["stop"],
            Command::Yes => &["yes", "correct"],
            Command::No => &["no", "wrong"],
            Command::GoToBallAndDribble => &["go to the ball and dribble", "dribble"],
            Command::Pass => &["pass the ball", "pass"],
            Command::Kick => &["kick the ball", "kick", "shoot"],
            Command::ClearBall => &["clear the ball"],
            Command::LookLeft => &["look left"],
            Command::LookRight => &["look right"],
            Command::LookAtBall => &["look at the ball"],
            Command::GoToPosition => &["go to your position", "go to position"],
            Command::SearchBall => &["search the ball", "search for the ball"],
            Command::Turn => &["turn around", "turn"],
            Command::AskForBall => &["ask for the ball"],
        }
    }

    /// The canonical phrase ("" for `None`): what the robot says back when it confirms.
    pub fn phrase(self) -> &'static str {
        self.phrases().first().copied().unwrap_or("")
    }

    /// Whether `game` understands this command.
    pub fn in_game(self, game: Game) -> bool {
        use Command::*;
        match self {
            None => false,
            Stop | Yes | No => true,
            Greet | Play | TrackBall | ScanBall | TouchBall | YouTouchedIt | Quit => {
                game == Game::Touch
            }
            _ => game == Game::Coach,
        }
    }

    /// The commands of `game`.
    pub fn of_game(game: Game) -> impl Iterator<Item = Command> {
        Command::ALL.into_iter().filter(move |c| c.in_game(game))
    }

    /// Whether this is a confirmation answer rather than a game action.
    pub fn is_answer(self) -> bool {
        matches!(self, Command::Yes | Command::No)
    }

    /// The command whose phrase `text` is (case, spacing and filler words ignored), among the
    /// commands of `game`; `None` when it is no command of that game.
    pub fn from_phrase(game: Game, text: &str) -> Command {
        let norm = normalize(text);
        if norm.is_empty() {
            return Command::None;
        }
        Command::of_game(game)
            .find(|c| c.phrases().iter().any(|p| *p == norm))
            .unwrap_or(Command::None)
    }
}

/// Lowercase, words split on whitespace, filler words dropped, joined by single spaces.
pub fn normalize(text: &str) -> String {
    text.split_whitespace()
        .map(str::to_lowercase)
        .filter(|w| !FILLER_WORDS.contains(&w.as_str()))
        .collect::<Vec<_>>()
        .join(" ")
}

/// Where a command came from.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum CommandSource {
    #[default]
    Voice,
    /// The command panel (buttons, clicks).
    Panel,
}

/// A validated command for the executive: published by `dialogs` once the recognizer was sure
/// enough or the person confirmed it, and by the command panel.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct GameCommand {
    pub header: Header,
    pub game: Game,
    pub command: Command,
    pub source: CommandSource,
    /// The words heard (voice) or the button's label (panel).
    pub text: String,
    /// Recognition confidence in [0, 1] (1 for the panel).
    pub confidence: f64,
    /// Whether the person confirmed it in a "Did you say ...?" exchange.
    pub confirmed: bool,
}

/// A yes/no answer to the dialog's confirmation question, from the command panel.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Answer {
    pub header: Header,
    /// `true` for yes.
    pub yes: bool,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_command_has_phrases_and_a_game_and_phrases_are_unique_per_game() {
        for c in Command::ALL {
            assert!(!c.phrases().is_empty(), "{c:?}");
            assert!(Game::ALL.iter().any(|g| c.in_game(*g)), "{c:?}");
            for p in c.phrases() {
                assert_eq!(normalize(p), *p, "{c:?}: phrase {p:?} is not normalised");
            }
        }
        for g in Game::ALL {
            let mut seen = std::collections::HashMap::new();
            for c in Command::of_game(g) {
                for p in c.phrases() {
                    assert!(seen.insert(*p, c).is_none(), "{p:?} used twice in {g:?}");
                    assert_eq!(Command::from_phrase(g, p), c);
                }
            }
        }
    }

    #[test]
    fn phrases_map_back_ignoring_case_spacing_and_fillers() {
        assert_eq!(
            Command::from_phrase(Game::Touch, "  Robot please TOUCH the   ball "),
            Command::TouchBall
        );
        assert_eq!(Command::from_phrase(Game::Coach, "kick"), Command::Kick);
        // Another game's command, nonsense and silence are no command.
        assert_eq!(
            Command::from_phrase(Game::Touch, "kick the ball"),
            Command::None
        );
        assert_eq!(
            Command::from_phrase(Game::Coach, "what a lovely day"),
            Command::None
        );
        assert_eq!(Command::from_phrase(Game::Coach, "please"), Command::None);
        assert_eq!(Command::from_phrase(Game::Coach, ""), Command::None);
        assert_eq!(Command::Stop.phrase(), "stop");
        assert_eq!(Command::None.phrase(), "");
    }
}
