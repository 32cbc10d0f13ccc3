use clap::Parser;
use command_generator::component::{Config, run};
use interfaces::node::{self, Interface, NodeArgs};
use interfaces::topics;
use std::net::SocketAddr;
use std::process::ExitCode;

/// The command panel: a web page with the games' buttons, the Nao coach's field and the robot's
/// answers. Open the printed address in a browser. Commands go on `coach/request` (the
/// Executive's coach machine checks them and commands the robot), `game/command` and
/// `game/answer`, checked first; refusals are shown on the page and counted on
/// `diagnostics` (`rejected/<reason>`).
///
/// By default only this machine can open it (127.0.0.1). To serve another machine, bind its
/// address with --http, add --allow-remote, and give a --token (or ROBOCOG_PANEL_TOKEN), then
/// open http://<address>/?token=<token>.
#[derive(Debug, Parser)]
#[command(version)]
struct Args {
    #[command(flatten)]
    node: NodeArgs,
    /// Address and port of the panel's HTTP server (port 0: any free port, printed at start).
    /// (`--listen` is the bus's own flag.)
    #[arg(long, default_value = "127.0.0.1:8642")]
    http: SocketAddr,
    /// Allow a non-loopback --http address (needs --token).
    #[arg(long)]
    allow_remote: bool,
    /// Access token the page must present (`/?token=...`); required with --allow-remote.
    #[arg(long, env = "ROBOCOG_PANEL_TOKEN", hide_env_values = true)]
    token: Option<String>,
    /// Camera images per second sent to each page (the camera itself runs at 30 Hz).
    #[arg(long, default_value_t = 4.0)]
    camera_hz: f64,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let interface = Interface {
        hardware: vec![format!("http:{}", args.http)],
        ..Interface::new("command_generator")
            .publishes(&topics::COACH_REQUEST)
            .publishes(&topics::GAME_COMMAND)
            .publishes(&topics::GAME_ANSWER)
            .subscribes(&topics::NAO_WORLD_MODEL)
            .subscribes(&topics::NAO_LOCAL_MODEL)
            .subscribes(&topics::NAO_GAME_STATE)
            .subscribes(&topics::NAO_LINK)
            .subscribes(&topics::VISION_RGBD)
            .subscribes(&topics::VISION_BALL)
            .subscribes(&topics::VISION_BALL_EVENTS)
            .subscribes(&topics::SPEECH_SAY)
            .subscribes(&topics::SPEECH_SPEAKING)
            .subscribes(&topics::SPEECH_UTTERANCE)
            .subscribes(&topics::GAME_COMMAND)
            .subscribes(&topics::EXECUTIVE_TRANSITIONS)
            .subscribes(&topics::EXECUTIVE_LOG)
            .subscribes(&topics::COACH_STATUS)
    };
    if !args.node.describe
        && let Err(e) =
            command_generator::check_listen(args.http, args.allow_remote, args.token.as_deref())
    {
        eprintln!("command_generator: error: {e}");
        return ExitCode::FAILURE;
    }
    if !(args.camera_hz > 0.0 && args.camera_hz <= 30.0) {
        eprintln!("command_generator: error: --camera-hz must be in (0, 30]");
        return ExitCode::FAILURE;
    }
    let config = Config {
        listen: args.http,
        token: args.token.filter(|t| !t.is_empty()),
        camera_hz: args.camera_hz,
    };
    node::run(args.node, interface, |bus, shutdown| {
        run(bus, config, shutdown)
    })
}
