//! The viewer component: a namespace's topics into rerun. See the library doc for the mapping.

use clap::Parser;
use interfaces::node::{self, NodeArgs};
use std::path::PathBuf;
use std::process::ExitCode;
use viewer::blueprint::Game;
use viewer::component::{self, Settings, Sink};

const ABOUT: &str = "\
Where the data goes (one of):\n\
\x20 --spawn                 start a rerun viewer (the `rerun` executable on PATH, from\n\
\x20                         `pip install rerun-sdk==0.36.3`) and stream to it; the default\n\
\x20 --connect-viewer URL    stream to a running viewer's gRPC endpoint, e.g.\n\
\x20                         rerun+http://127.0.0.1:9876/proxy (start it with `rerun`)\n\
\x20 --save FILE.rrd         write a recording; open it later with `rerun FILE.rrd`\n\
\n\
Every topic of the namespace is picked up as it appears (or only --topics). Samples are\n\
decoded by their type name; unknown types and undecodable payloads are listed once, counted\n\
(view_unknown/<topic>, view_undecodable/<topic>) and skipped. A viewer slower than the robot\n\
makes this component drop samples (view_dropped/<topic>, also drawn under stats/), never the\n\
publishers wait. Camera frames are thinned to --image-hz.\n\
\n\
Examples:\n\
\x20 robocog view                                    # spawn a viewer, every topic\n\
\x20 robocog view --save game.rrd --game touch\n\
\x20 robocog view --connect-viewer rerun+http://10.0.0.5:9876/proxy --exclude audio/in";

/// Logs the live topics of a robocog namespace to rerun.
#[derive(Debug, Parser)]
#[command(name = "viewer", after_help = ABOUT)]
struct Args {
    #[command(flatten)]
    node: NodeArgs,
    /// Start a rerun viewer and stream to it (the default when neither --save nor
    /// --connect-viewer is given).
    #[arg(long, conflicts_with_all = ["save", "connect_viewer"])]
    spawn: bool,
    /// Stream to a running rerun viewer at this gRPC URL (rerun+http://HOST:PORT/proxy).
    #[arg(long, value_name = "URL", conflicts_with = "save")]
    connect_viewer: Option<String>,
    /// Write everything to this .rrd file instead (finished on SIGTERM or Ctrl-C).
    #[arg(long, value_name = "FILE")]
    save: Option<PathBuf>,
    /// Only these topics (comma-separated). Default: every topic of the namespace.
    #[arg(long, value_delimiter = ',', value_name = "TOPIC,...")]
    topics: Vec<String>,
    /// Leave these topics out (comma-separated).
    #[arg(long, value_delimiter = ',', value_name = "TOPIC,...")]
    exclude: Vec<String>,
    /// The layout of the views. Default: chosen from the topics present (Nao topics: coach;
    /// camera, body or ball topics: touch); rerun's automatic layout until one is seen.
    #[arg(long, value_enum)]
    game: Option<Game>,
    /// The robot's URDF (default: models/loki.urdf found beside the binaries or the current
    /// folder). Joint states and camera frames are drawn on it.
    #[arg(long, value_name = "FILE")]
    urdf: Option<PathBuf>,
    /// The SPL field model (default: models/spl_field.toml), for the coach game's field lines.
    #[arg(long, value_name = "FILE")]
    field: Option<PathBuf>,
    /// At most this many camera frames per second go to rerun (0: all of them; a 640x480 RGB-D
    /// frame is about 1.5 MB).
    #[arg(long, default_value_t = 10.0, value_name = "HZ")]
    image_hz: f64,
    /// At most this many samples wait for rerun; more are dropped (and counted).
    #[arg(long, default_value_t = 256, value_name = "N")]
    queue: usize,
    /// At most this many of them from one topic.
    #[arg(long, default_value_t = 32, value_name = "N")]
    queue_per_topic: usize,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let sink = match (&args.save, &args.connect_viewer) {
        (Some(p), _) => Sink::Save(p.clone()),
        (None, Some(u)) => Sink::Connect(u.clone()),
        (None, None) => Sink::Spawn,
    };
    let settings = Settings {
        sink,
        topics: args.topics,
        exclude: args.exclude,
        game: args.game,
        urdf: args.urdf,
        field: args.field,
        image_hz: args.image_hz,
        queue: args.queue,
        queue_per_topic: args.queue_per_topic,
    };
    node::run(args.node, component::interface(), move |bus, shutdown| {
        component::run(bus, settings, shutdown)
    })
}
