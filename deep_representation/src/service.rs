//! The `deep_representation` component: the scene graph served over the bus.
//!
//! One live [`SceneGraph`] per process, behind a read-write lock: queries (node, transform,
//! predicate, fork, PDDL, snapshot) share it, changes (update, propose, restore) take it alone.
//!
//! | service (`interfaces::topics`) | does |
//! |---|---|
//! | `dr/get_node` | one node: type, parent, children, edge, pose, attributes, its full description |
//! | `dr/transform` | `target_T_source`, latest or at a past time (interpolated from the edge histories) |
//! | `dr/update` | attributes, free poses, joint values, straight in; the batch is checked first and applied whole or not at all |
//! | `dr/propose` | a structural change; accepted or rejected with the integrity rule that refused it |
//! | `dr/predicate` | whether a predicate holds, or every fact that holds |
//! | `dr/fork` | virtual actions on a private copy; predicate changes, joints changed, items moved (the live graph untouched) |
//! | `dr/pddl` | the state as a PDDL problem text |
//! | `dr/snapshot`, `dr/restore` | the state as a typed snapshot (every node's description, the body parts); replace the state with one |
//!
//! Every accepted change is published on `dr/changes` (in order, with a sequence number that
//! continues across restarts) and, with a state folder, appended to its change log before the
//! reply leaves (see [`world_model::persist`]).
//!
//! Bus messages and library types meet in `world_model::bus` (conversions both ways).
//!
//! Errors: an unknown node, frame or joint is a `NotFound` [`ServiceError`]; a malformed request
//! (a non-finite number, an attribute given twice, a wrong argument count, a negative stamp) is
//! `BadRequest`; a rejected proposal is a normal reply. Time: the stamp of a change is the
//! request's `header.stamp_ns`, or now on the bus clock when it is 0.

use std::path::PathBuf;
use std::time::Duration;

use interfaces::node::Interface;
use interfaces::{Bus, Shutdown, topics};

use robot_model::RobotModel;
use world_model::field::FieldModel;
use world_model::graph::SceneGraph;
use world_model::persist::StoreOptions;
use world_model::predicates::PredicateConfig;
use world_model::scenes;
use world_model::types::Stamp;

/// The start scene used when the state folder holds no state (or there is none).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Scene {
    /// Loki, the player and the ball ([`scenes::touch_the_ball`]); needs the URDF.
    Touch,
    /// The SPL field, four robots, the ball, the coach ([`scenes::coach_game`]); needs the field.
    Coach,
    /// Only `world`.
    Empty,
}

/// How the service runs.
#[derive(Debug, Clone)]
pub struct ServiceConfig {
    /// State folder (snapshot + change log); `None`: in memory only.
    pub state_dir: Option<PathBuf>,
    /// Start scene.
    pub scene: Scene,
    /// The robot's URDF (for [`Scene::Touch`]).
    pub urdf: PathBuf,
    /// The SPL field model (for [`Scene::Coach`]).
    pub field: PathBuf,
    /// Persistence options.
    pub store: StoreOptions,
    /// Predicate thresholds.
    pub predicates: PredicateConfig,
    /// Samples kept per edge.
    pub history_len: usize,
    /// Follow the measured joints: subscribe `body/joint_states` and apply them to the robot's
    /// joint edges (see [`follow_joint_states`]).
    pub follow_joint_states: bool,
}

impl ServiceConfig {
    /// A config for `scene` with the repository's models (found as [`find_model`] does), in
    /// memory.
    pub fn new(scene: Scene) -> Self {
        Self {
            state_dir: None,
            scene,
            urdf: find_model(None, "loki.urdf"),
            field: find_model(None, "spl_field.toml"),
            store: StoreOptions::default(),
            predicates: PredicateConfig::default(),
            history_len: SceneGraph::DEFAULT_HISTORY_LEN,
            follow_joint_states: false,
        }
    }

    /// The start scene.
    pub fn start_scene(&self) -> world_model::Result<SceneGraph> {
        match self.scene {
            Scene::Touch => {
                let loki = RobotModel::from_urdf_file(&self.urdf)?;
                scenes::touch_the_ball(&loki, Stamp(0))
            }
            Scene::Coach => {
                let field = FieldModel::from_file(&self.field)?;
                scenes::coach_game(&field, Stamp(0))
            }
            Scene::Empty => Ok(SceneGraph::new()),
        }
    }
}

pub use robot_model::find_model;

/// The component's interface (what `--describe` prints).
pub fn interface() -> Interface {
    interface_with(false)
}

/// The interface, with the `body/joint_states` subscription when `follow_joint_states`.
pub fn interface_with(follow_joint_states: bool) -> Interface {
    let i = Interface::new("deep_representation");
    let i = if follow_joint_states {
        i.subscribes(&topics::BODY_JOINT_STATES)
    } else {
        i
    };
    i.publishes(&topics::DR_CHANGES)
        .serves(&topics::DR_GET_NODE)
        .serves(&topics::DR_TRANSFORM)
        .serves(&topics::DR_UPDATE)
        .serves(&topics::DR_PROPOSE)
        .serves(&topics::DR_PREDICATE)
        .serves(&topics::DR_FORK)
        .serves(&topics::DR_PDDL)
        .serves(&topics::DR_SNAPSHOT)
        .serves(&topics::DR_RESTORE)
}

// ---------------------------------------------------------------- conversions

mod dr;
mod start;
pub use dr::Dr;
pub use start::{JOINT_STATES_MIN_INTERVAL, Running, follow_joint_states, start};

/// The component: [`start`], serve until `shutdown`, write a final snapshot.
pub async fn run(bus: Bus, config: ServiceConfig, mut shutdown: Shutdown) -> anyhow::Result<()> {
    let running = start(bus, config).await?;
    shutdown.wait().await;
    running.dr.checkpoint().await;
    // Let queued change events leave before the process ends.
    #[expect(
        clippy::disallowed_methods,
        reason = "queued change events drain to the transport on the wall: a replay's clock may never move again"
    )]
    tokio::time::sleep(Duration::from_millis(50)).await;
    tracing::info!("stopped");
    Ok(())
}

/// The service's flags.
#[derive(Debug, Clone, clap::Args)]
pub struct Flags {
    /// Keep the state here (snapshot + change log) and recover it on start. Under `robocog
    /// launch` it defaults to the component's state folder (ROBOCOG_STATE_DIR), so a restarted
    /// DR takes up the world where it was; without either the state lives in memory only.
    #[arg(long, env = "ROBOCOG_STATE_DIR")]
    pub state_dir: Option<PathBuf>,
    /// Start scene when there is no saved state.
    #[arg(long, value_enum, default_value_t = Scene::Touch)]
    pub scene: Scene,
    /// The robot's URDF (default: models/loki.urdf found above the binary or the working folder).
    #[arg(long, env = "ROBOCOG_URDF")]
    pub urdf: Option<PathBuf>,
    /// The SPL field model (default: models/spl_field.toml, found like the URDF).
    #[arg(long, env = "ROBOCOG_FIELD")]
    pub field: Option<PathBuf>,
    /// Write a fresh snapshot every this many changes.
    #[arg(long, default_value_t = 1000)]
    pub compact_every: usize,
    /// fdatasync the change log after every change (survives a power loss, costs a disk flush).
    #[arg(long)]
    pub fsync: bool,
    /// Follow the measured joints: subscribe body/joint_states (from joint_motor) and apply them
    /// to the robot's joints, so transforms of the hands and the head camera follow the body.
    #[arg(long)]
    pub follow_joint_states: bool,
}

/// The `deep_representation` component.
#[derive(Debug)]
pub struct DeepRepresentation;

impl interfaces::node::Component for DeepRepresentation {
    const NAME: &'static str = "deep_representation";
    const ABOUT: &'static str =
        "The deep representation: robocog's world model, served on the bus.";
    type Config = Flags;
    type Prepared = ServiceConfig;

    fn interface(config: &Flags) -> Interface {
        interface_with(config.follow_joint_states)
    }

    fn prepare(config: Flags) -> anyhow::Result<ServiceConfig> {
        Ok(ServiceConfig {
            state_dir: config.state_dir,
            scene: config.scene,
            urdf: find_model(config.urdf.as_deref(), "loki.urdf"),
            field: find_model(config.field.as_deref(), "spl_field.toml"),
            store: StoreOptions {
                compact_every: config.compact_every.max(1),
                fsync: config.fsync,
            },
            follow_joint_states: config.follow_joint_states,
            ..ServiceConfig::new(config.scene)
        })
    }

    async fn run(bus: Bus, prepared: ServiceConfig, shutdown: Shutdown) -> anyhow::Result<()> {
        run(bus, prepared, shutdown).await
    }
}
