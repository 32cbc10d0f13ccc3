//! The viewer layout for each game, as a rerun blueprint (built with the Rust SDK's blueprint API
//! and sent with the recording, so a saved `.rrd` opens with the same layout).
//!
//! - **touch** (Loki's "touch the ball"): the robot, the ball and the reach marks in 3D; the head
//!   camera's image with the tracker's window; the depth image; the game's text logs; the rates.
//! - **coach** (the Nao coach game): the field from above (2D) and in 3D; the text logs; the
//!   rates.

use rerun::blueprint::{
    Blueprint, ContainerLike, Horizontal, Spatial2DView, Spatial3DView, Tabs, TextLogView,
    TimeSeriesView, Vertical,
};

/// Which game's layout.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Game {
    /// Loki's "touch the ball".
    Touch,
    /// The Nao coach game.
    Coach,
}

impl Game {
    /// The game a set of topic names belongs to: the Nao topics (`nao/*`, `coach/*`,
    /// `sim/field_truth`) mean the coach game; camera, body and ball topics the touch game.
    pub fn from_topics<'a>(topics: impl IntoIterator<Item = &'a str>) -> Option<Game> {
        let mut touch = false;
        for t in topics {
            if t.starts_with("nao/") || t.starts_with("coach/") || t == "sim/field_truth" {
                return Some(Game::Coach);
            }
            if t.starts_with("vision/") || t.starts_with("body/") || t == "sim/ball" {
                touch = true;
            }
        }
        touch.then_some(Game::Touch)
    }
}

fn view(v: impl Into<ContainerLike>) -> ContainerLike {
    v.into()
}

/// The layout of `game`; `camera` is the entity the head camera's pinhole is logged at
/// ([`crate::mapping::Mapper::camera_path`]).
pub fn blueprint(game: Game, camera: &str) -> Blueprint {
    let logs = view(TextLogView::new("Game log").with_origin("log"));
    let rates = view(
        Tabs::new([
            view(TimeSeriesView::new("Rates (Hz)").with_origin("stats/rate_hz")),
            view(TimeSeriesView::new("Latency (ms)").with_origin("stats/latency_ms")),
            view(TimeSeriesView::new("Dropped").with_origin("stats/dropped")),
        ])
        .with_name("Topics"),
    );
    let root = match game {
        Game::Touch => Horizontal::new([
            view(Tabs::new([
                view(
                    // The depth image would be back-projected into a point cloud that hides
                    // the robot: it has its own 2D view.
                    Spatial3DView::new("Robot and ball")
                        .with_origin("world")
                        .with_contents(["+ world/**".to_string(), format!("- {camera}/depth")]),
                ),
                view(Spatial3DView::new("Deep representation").with_origin("dr")),
            ])),
            view(
                Vertical::new([
                    view(
                        Spatial2DView::new("Head camera")
                            .with_origin(camera)
                            .with_contents([
                                format!("{camera}/rgb"),
                                format!("{camera}/ball_window"),
                            ]),
                    ),
                    view(
                        Spatial2DView::new("Depth")
                            .with_origin(camera)
                            .with_contents([format!("{camera}/depth")]),
                    ),
                ])
                .with_name("Camera"),
            ),
            view(Vertical::new([logs, rates]).with_name("Logs")),
        ])
        .with_column_shares([2.0, 1.5, 1.5]),
        Game::Coach => Horizontal::new([
            view(
                Vertical::new([
                    view(Spatial2DView::new("Field").with_origin("field2d")),
                    view(Tabs::new([
                        view(Spatial3DView::new("Field 3D").with_origin("field3d")),
                        view(Spatial3DView::new("Deep representation").with_origin("dr")),
                    ])),
                ])
                .with_name("Field"),
            ),
            view(Vertical::new([logs, rates]).with_name("Logs")),
        ])
        .with_column_shares([2.0, 1.0]),
    };
    Blueprint::new(root)
        .with_auto_views(false)
        .with_auto_layout(false)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_game_follows_the_topics() {
        assert_eq!(
            Game::from_topics(["diagnostics", "vision/rgbd", "executive/log"]),
            Some(Game::Touch)
        );
        assert_eq!(
            Game::from_topics(["vision/rgbd", "nao/world_model"]),
            Some(Game::Coach)
        );
        assert_eq!(Game::from_topics(["chatter", "diagnostics"]), None);
    }
}
