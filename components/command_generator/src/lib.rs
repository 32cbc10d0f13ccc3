//! The command panel (seed 001's CommandGenerator; seed 000's coach interface): the games'
//! commands from a web page, for players who cannot or would rather not speak, and for the Nao
//! coach who needs buttons, a field and a click.
//!
//! # Concepts
//!
//! - **One HTTP server**, on `127.0.0.1:8642` by default. The page, its script and its style are
//!   compiled into the binary (`web/`): no build step, no network, no CDN. Binding another
//!   address (`--http`) needs `--allow-remote` and a `--token` the page must present (`/?token=...`).
//! - **Two views** of one page: *touch* (Loki's touch-the-ball: camera image with the ball's
//!   window and 3D position, the Executive's state, the dialog, the game's buttons and yes/no)
//!   and *coach* (the Nao game: the SPL field to scale with the fused world model, the game
//!   state, link health, buttons for every command, a click on the field for GoToPosition's and
//!   Turn's target, the spoken answers, the command history).
//! - **Every request is checked on the server** ([`protocol`]) before anything is published;
//!   refusals carry a reason the page shows, are counted on `diagnostics` as
//!   `rejected/<reason>`, and are never forwarded.
//! - **Commands go through the Executive, like voice commands**: coach commands as a
//!   [`interfaces::msg::nao::CoachRequest`] on `coach/request` (its `command` a `NaoCommand` with
//!   `source = "panel"`), which the Executive's coach machine answers, checks against the game
//!   state and the world model, and only then sends on `nao/command`; touch commands on
//!   `game/command` (a [`interfaces::msg::command::GameCommand`], `source = Panel`, confidence
//!   1); yes/no on `game/answer`. The panel never commands the robot directly.
//! - **The talk key** ("Hold to talk", or V held): `speech/talk` for a recognizer in
//!   push-to-talk mode, sent as it goes down, every 0.5 s while it is held (the page repeats it),
//!   and as it comes up; a page that goes while holding it has it let up by the server. Only its
//!   going down and up are in the history.
//!
//! Field frame (coach view): millimetres, origin at the centre spot, x towards the opponent
//! goal, y to the left, angles counter-clockwise from +x: the frame of `interfaces::msg::nao`.
//!
//! # The WebSocket (`/ws`)
//!
//! One connection per page, JSON text both ways, plus binary camera images from the server.
//!
//! Page to server: the requests of [`protocol`] (`command`, `nao`, `strategy`, `answer`,
//! `talk`), at most [`protocol::MAX_MESSAGE_BYTES`] each. A message over
//! [`server::HARD_MESSAGE_LIMIT`] closes that connection (the page reconnects); everything
//! smaller gets a reply.
//!
//! Server to page, each a JSON object with a `type`:
//!
//! | `type` | fields | when |
//! |---|---|---|
//! | `hello` | `catalog` (buttons, shortcuts, field size), `strategy`, `max_message_bytes`, `server_time_ms` (the panel's clock, ms since the Unix epoch), `stale_after_ms` | on connect |
//! | `reply` | `id` (the request's), `ok`, `entry` (the history entry: `label`, `status`, `reason`, `target`) | after each request |
//! | `history` | `entries` (oldest first; `status` is `accepted`, `refused`, `replaced` or `pending`) | on connect and on every change |
//! | `state` | `topic`, `data` (the bus message as JSON) | the latest of `nao/world_model`, `nao/local_model` (per robot), `nao/game_state`, `vision/ball`, `executive/transitions` (per machine), `speech/listening`, `vision/rgbd` (image size, stamp, sequence number, and `track`: the `vision/ball` result for that very frame, or null), each at most at its rate of [`component::STATE_RATES`] |
//! | `coach_status` | the coach machine's state, pending command and why it waits, last command, last-seen ages of ball and obstacles, link: see [`coach_status`] | the latest `coach/status`, at most 4 a second |
//! | `event` | `topic`, `data` | every message of `nao/link`, `speech/say`, `speech/speaking`, `speech/utterance`, `game/command`, `executive/log`, `vision/ball_events`; the last [`server::EVENT_REPLAY`] are replayed on connect |
//!
//! A binary message is the latest camera image (JPEG), at most `--camera-hz` a second; the
//! `vision/rgbd` state sent just before it describes it (original size, so the ball's window in
//! pixels scales onto the shown image).

pub mod camera;
pub mod catalog;
pub mod coach_status;
pub mod component;
pub mod panel;
pub mod protocol;
pub mod server;

use std::net::SocketAddr;

/// Why the panel refuses to start.
#[derive(Debug, PartialEq, thiserror::Error)]
pub enum StartError {
    #[error(
        "refusing to listen on {0}, which is not a loopback address: the panel drives a robot. \
         Pass --allow-remote and a --token (at least {MIN_TOKEN_LEN} characters) that the page must present"
    )]
    RemoteNotAllowed(SocketAddr),
    #[error(
        "refusing to listen on {0} without a token: pass --token (at least {MIN_TOKEN_LEN} characters, \
         or set ROBOCOG_PANEL_TOKEN)"
    )]
    NoToken(SocketAddr),
    #[error("the token is too short: at least {MIN_TOKEN_LEN} characters")]
    ShortToken,
}

/// Shortest accepted token.
pub const MIN_TOKEN_LEN: usize = 12;

/// Check where the panel may listen: loopback always; anything else only with `allow_remote`
/// and a token of at least [`MIN_TOKEN_LEN`] characters.
pub fn check_listen(
    listen: SocketAddr,
    allow_remote: bool,
    token: Option<&str>,
) -> Result<(), StartError> {
    let token = token.filter(|t| !t.is_empty());
    if let Some(t) = token
        && t.chars().count() < MIN_TOKEN_LEN
    {
        return Err(StartError::ShortToken);
    }
    if listen.ip().is_loopback() {
        return Ok(());
    }
    if !allow_remote {
        return Err(StartError::RemoteNotAllowed(listen));
    }
    if token.is_none() {
        return Err(StartError::NoToken(listen));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_loopback_without_a_flag_and_a_token() {
        let lo: SocketAddr = "127.0.0.1:8642".parse().expect("addr");
        let any: SocketAddr = "0.0.0.0:8642".parse().expect("addr");
        let lan: SocketAddr = "[::]:8642".parse().expect("addr");
        assert_eq!(check_listen(lo, false, None), Ok(()));
        assert_eq!(
            check_listen("[::1]:1".parse().expect("addr"), false, None),
            Ok(())
        );
        assert_eq!(
            check_listen(any, false, None),
            Err(StartError::RemoteNotAllowed(any))
        );
        assert_eq!(
            check_listen(any, false, Some("long-enough-token")),
            Err(StartError::RemoteNotAllowed(any))
        );
        assert_eq!(check_listen(lan, true, None), Err(StartError::NoToken(lan)));
        assert_eq!(
            check_listen(lan, true, Some("")),
            Err(StartError::NoToken(lan))
        );
        assert_eq!(
            check_listen(any, true, Some("short")),
            Err(StartError::ShortToken)
        );
        assert_eq!(check_listen(any, true, Some("long-enough-token")), Ok(()));
        let msg = check_listen(any, false, None)
            .expect_err("refused")
            .to_string();
        assert!(
            msg.contains("--allow-remote") && msg.contains("--token"),
            "{msg}"
        );
    }
}
