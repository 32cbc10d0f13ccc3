//! The `joint_motor` component: a [`JointMotor`] (driver + ownership rule) on the bus.
//!
//! Publishes `body/joint_states` ([`interfaces::msg::body::JointStates`]) at `--rate-hz`
//! (default 100 Hz): every joint of the driver, with its owner (empty: nobody) and the driver's
//! name, stamped with the bus clock.
//!
//! Serves `body/joint_goal` ([`interfaces::msg::body::JointGoal`] →
//! [`interfaces::msg::body::JointGoalReply`]): a goal is accepted or refused as a whole, with
//! the typed reason, the joint, the limit, the value requested and the owner (see the crate docs,
//! "Ownership"). `release = true` gives joints back. A refusal is a normal reply, counted on
//! `diagnostics` per reason (`refused/<reason>`), never a service error.
//!
//! Joints: every movable joint of the URDF (`--urdf`, default `models/loki.urdf` found as the
//! deep representation finds it), with the URDF's position and velocity limits; URDF has no
//! acceleration limit, so each joint may reach its maximum velocity in `--accel-time-s`.
//! With `--driver dynamixel`, only the joints mapped in `--servo-config` are driven.
//!
//! The Stewart neck: when the URDF declares one (`<robocog_stewart_neck>`), its pitch, roll and
//! yaw joints are driven through the platform's three legs ([`crate::neck::NeckDriver`]): the
//! goal angles become leg lengths (inverse kinematics), and the published angles come from the
//! measured lengths (forward kinematics), so the head's pose, and the camera's, is the one the
//! legs give. `--driver sim` simulates the legs; `--driver dynamixel` drives them when the servo
//! map names them (prismatic, `m_per_rad`), or the three joints as servos of their own when it
//! names those. A goal whose legs would leave their stroke is clamped to the nearest reachable
//! pose, counted on `diagnostics` (`neck/clamped`) and logged. An inconsistent platform (the home
//! pose out of the stroke, an axis unobservable) stops the component at start, naming why.
//!
//! Time: the drivers run on the process's monotonic clock (seconds since start); messages carry
//! the bus clock.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::Context;
use interfaces::msg::body as m;
use interfaces::node::Interface;
use interfaces::ratelimit::RateLimiter;
use interfaces::{Bus, Shutdown, topics};
use robot_model::find_model;
use robot_model::{JointKind as UrdfKind, RobotModel};

use crate::bus::{self, Request};
use crate::driver::JointDriver;
use crate::home::Home;
use crate::neck::NeckPlan;
use crate::ownership::JointMotor;
use crate::sim::{SimDriver, SimParams};
use crate::stewart::NeckAngles;
use crate::types::{JointCommand, JointGoal, JointRelease, JointSpec, JointTarget};

/// The component's flags.
#[derive(Debug, Clone, clap::Args)]
pub struct Config {
    /// Which driver moves the joints: `sim` (simulated joints, no hardware) or `dynamixel`
    /// (X-series servos, Protocol 2.0 over a serial port; needs --servo-config).
    #[arg(long, default_value = "sim", value_parser = ["sim", "dynamixel"])]
    pub driver: String,
    /// The robot's URDF: the joints and their limits (default: models/loki.urdf, found above the
    /// binary or the working folder, as deep_representation does).
    #[arg(long, env = "ROBOCOG_URDF")]
    pub urdf: Option<PathBuf>,
    /// Joint states publication rate (Hz).
    #[arg(long, default_value_t = 100.0)]
    pub rate_hz: f64,
    /// A client keeps its joints this long (s) after its last goal naming them.
    #[arg(long, default_value_t = 1.0)]
    pub lease_s: f64,
    /// Start posture: `rest` (arms hanging beside the body, head ahead 17° down; see
    /// `joint_motor::home`), `zero`, or `none` (command nothing at start).
    #[arg(long, value_enum, default_value_t = Home::Rest)]
    pub home: Home,
    /// Time (s) for a joint to reach its maximum velocity from rest: the acceleration limit is
    /// the URDF velocity limit divided by this.
    #[arg(long, default_value_t = 0.25)]
    pub accel_time_s: f64,
    /// Optional TOML file of the sim driver (`time_constant_s`, `substep_s`).
    #[arg(long)]
    pub sim_config: Option<PathBuf>,
    /// Dynamixel: the servo map, a TOML file (port, baud, time-outs, `[joints.<name>]` id, sign,
    /// offset_rad; see `joint_motor::dynamixel::config`).
    #[arg(long)]
    pub servo_config: Option<PathBuf>,
    /// Dynamixel: the serial device, overriding the servo map's `port`.
    #[arg(long)]
    pub port: Option<String>,
    /// Dynamixel: speed (rad/s) of the move to the start posture.
    #[arg(long, default_value_t = 0.3)]
    pub home_speed: f64,
    /// Sim: keep the simulated joints' posture here, and start from it after a restart, as real
    /// servos hold where they are while their driver restarts (under `robocog launch`: the
    /// component's state folder, ROBOCOG_STATE_DIR; a new launch starts from `--home`).
    #[arg(long, env = "ROBOCOG_STATE_DIR")]
    pub state_dir: Option<PathBuf>,
}

/// What the component declares for `--describe`.
pub fn interface() -> Interface {
    Interface::new("joint_motor")
        .publishes(&topics::BODY_JOINT_STATES)
        .serves(&topics::BODY_JOINT_GOAL)
}

/// The driver's joint specs for every movable joint of `model` (URDF position and velocity
/// limits; acceleration = velocity / `accel_time_s`).
pub fn specs_from_model(model: &RobotModel, accel_time_s: f64) -> anyhow::Result<Vec<JointSpec>> {
    anyhow::ensure!(
        accel_time_s.is_finite() && accel_time_s > 0.0,
        "--accel-time-s must be > 0, got {accel_time_s}"
    );
    let mut specs = Vec::new();
    for j in &model.joints {
        let l = j.limits;
        let spec = match j.kind {
            UrdfKind::Fixed => continue,
            UrdfKind::Continuous => anyhow::bail!(
                "joint `{}` is continuous: joint_motor needs position limits on every joint",
                j.name
            ),
            UrdfKind::Revolute => JointSpec::revolute(
                &j.name,
                l.lower,
                l.upper,
                l.velocity,
                l.velocity / accel_time_s,
            ),
            UrdfKind::Prismatic => JointSpec::prismatic(
                &j.name,
                l.lower,
                l.upper,
                l.velocity,
                l.velocity / accel_time_s,
            ),
        };
        specs.push(spec);
    }
    Ok(specs)
}

/// The client name of the start-posture move (dynamixel).
pub const HOME_CLIENT: &str = "joint_motor/home";

fn open(
    config: &Config,
    specs: Vec<JointSpec>,
    neck: Option<&NeckPlan>,
) -> anyhow::Result<Box<dyn JointDriver>> {
    match config.driver.as_str() {
        "sim" => {
            let params = match &config.sim_config {
                Some(p) => SimParams::from_toml(
                    &std::fs::read_to_string(p)
                        .with_context(|| format!("reading {}", p.display()))?,
                )
                .with_context(|| format!("in {}", p.display()))?,
                None => SimParams::default(),
            };
            let kept = config.state_dir.as_deref().and_then(crate::kept::load);
            if let Some(k) = &kept {
                tracing::info!(
                    "the simulated joints take up the posture they had before a restart ({} joints)",
                    k.len()
                );
            }
            // Each joint where it was kept (within its limits), else at the start posture,
            // else at 0 (within its limits).
            let start_of = |s: &JointSpec| {
                kept.as_ref()
                    .and_then(|k| k.get(&s.name))
                    .copied()
                    .filter(|q| (s.lower..=s.upper).contains(q))
                    .or_else(|| config.home.position(&s.name, s.lower, s.upper))
                    .unwrap_or_else(|| 0.0_f64.clamp(s.lower, s.upper))
            };
            let Some(neck) = neck else {
                let start: Vec<f64> = specs.iter().map(start_of).collect();
                return Ok(Box::new(SimDriver::new_at(specs, params, &start)?));
            };
            // A simulated platform: its legs start at the lengths of the neck's start pose.
            let [pitch, roll, yaw] = neck.axes.clone().map(|a| start_of(&a));
            let lengths = neck.leg_lengths(NeckAngles { pitch, roll, yaw })?;
            let inner = neck.inner_specs(&specs);
            let start: Vec<f64> = inner
                .iter()
                .map(|s| match neck.legs.iter().position(|l| l.name == s.name) {
                    Some(k) => lengths[k],
                    None => start_of(s),
                })
                .collect();
            let sim = SimDriver::new_at(inner, params, &start)?;
            tracing::info!(
                "the neck is a simulated Stewart platform: {}, {} and {} move its legs {}, {} and {}",
                neck.axes[0].name,
                neck.axes[1].name,
                neck.axes[2].name,
                neck.legs[0].name,
                neck.legs[1].name,
                neck.legs[2].name
            );
            Ok(Box::new(neck.wrap(Box::new(sim))?))
        }
        "dynamixel" => {
            let path = config.servo_config.as_ref().with_context(|| {
                format!("--driver dynamixel needs --servo-config <file.toml> (Loki's: {EXAMPLE_SERVO_MAP})")
            })?;
            let offered = match neck {
                Some(n) => specs
                    .iter()
                    .cloned()
                    .chain(n.legs.iter().cloned())
                    .collect(),
                None => specs,
            };
            let (specs, mut cfg) = load_servo_map(path, offered)?;
            if let Some(port) = &config.port {
                cfg.port.clone_from(port);
            }
            // The neck's legs mapped: the platform is driven through them; else its pitch, roll
            // and yaw, if mapped, are servos of their own.
            let platform = match neck {
                Some(n) => {
                    let legs = specs.iter().filter(|s| n.is_leg(&s.name)).count();
                    let axes = specs.iter().filter(|s| n.is_axis(&s.name)).count();
                    anyhow::ensure!(
                        legs == 0 || (legs == 3 && axes == 0),
                        "{}: the servo map names {legs} of the neck's 3 legs and {axes} of its pitch, roll and yaw joints: map the three legs (a Stewart neck) or the joints (a neck of three servos), not both",
                        path.display()
                    );
                    (legs == 3).then_some(n)
                }
                None => None,
            };
            let serial = crate::dynamixel::SerialPort::open(&cfg.port, cfg.baud)
                .with_context(|| format!("opening the servo line {}", cfg.port))?;
            tracing::info!(
                port = %cfg.port,
                baud = cfg.baud,
                joints = specs.len(),
                stewart_neck = platform.is_some(),
                "connecting to the servos"
            );
            let servos = Box::new(crate::dynamixel::DynamixelDriver::new(
                specs,
                cfg,
                Box::new(serial),
            )?);
            Ok(match platform {
                Some(n) => Box::new(n.wrap(servos)?),
                None => servos,
            })
        }
        other => anyhow::bail!("unknown driver `{other}` (known: sim, dynamixel)"),
    }
}

/// The component ready to run: its flags, the robot model's path and the opened driver.
pub struct Prepared {
    config: Config,
    urdf: PathBuf,
    driver: Box<dyn JointDriver>,
}

impl std::fmt::Debug for Prepared {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Prepared")
            .field("config", &self.config)
            .field("urdf", &self.urdf)
            .field("driver", &self.driver.name())
            .finish()
    }
}

/// Checks the flags, loads the robot model and opens the driver (the servo map, the serial
/// line): everything a restart could not fix fails here, before the component joins the bus.
pub fn prepare(config: Config) -> anyhow::Result<Prepared> {
    anyhow::ensure!(
        config.rate_hz.is_finite() && config.rate_hz > 0.0 && config.rate_hz <= 1000.0,
        "--rate-hz must be in (0, 1000], got {}",
        config.rate_hz
    );
    let urdf = find_model(config.urdf.as_deref(), "loki.urdf");
    let model = RobotModel::from_urdf_file(&urdf)
        .with_context(|| format!("loading the robot model {}", urdf.display()))?;
    let specs = specs_from_model(&model, config.accel_time_s)?;
    let neck = NeckPlan::from_model(&model, &specs, config.accel_time_s).with_context(|| {
        format!(
            "the neck platform of {} (its <robocog_stewart_neck> element)",
            urdf.display()
        )
    })?;
    let driver = open(&config, specs, neck.as_ref())?;
    Ok(Prepared {
        config,
        urdf,
        driver,
    })
}

/// Where the repository keeps a commented servo map for Loki.
pub const EXAMPLE_SERVO_MAP: &str = "models/loki_servos.example.toml";

/// The servo map at `path`, checked against the robot's joints `specs`: the specs of the joints
/// it maps (the only ones the dynamixel driver drives) and the driver's configuration.
pub fn load_servo_map(
    path: &std::path::Path,
    specs: Vec<JointSpec>,
) -> anyhow::Result<(Vec<JointSpec>, crate::dynamixel::DynamixelConfig)> {
    let text = std::fs::read_to_string(path).with_context(|| {
        format!(
            "reading the servo map {} (a commented one for Loki: {EXAMPLE_SERVO_MAP})",
            path.display()
        )
    })?;
    // Drive only the joints the servo map names.
    let table: toml::Table =
        toml::from_str(&text).with_context(|| format!("in {}", path.display()))?;
    let mapped: Vec<String> = table
        .get("joints")
        .and_then(|j| j.as_table())
        .map(|t| t.keys().cloned().collect())
        .unwrap_or_default();
    let specs: Vec<JointSpec> = specs
        .into_iter()
        .filter(|s| mapped.contains(&s.name))
        .collect();
    let cfg = crate::dynamixel::DynamixelConfig::from_toml(&text, &specs)
        .with_context(|| format!("in {}", path.display()))?;
    Ok((specs, cfg))
}

/// Runs the component until shutdown.
pub async fn run(bus: Bus, prepared: Prepared, mut shutdown: Shutdown) -> anyhow::Result<()> {
    let Prepared {
        config,
        urdf,
        driver,
    } = prepared;
    let driver_name = driver.name();
    let joints = driver.joints().len();
    let mut motor = JointMotor::new(driver, config.lease_s)?;
    // The motor's time (goals, leases, the simulated servos' motion) is the component's clock.
    let clock = bus.clock().clone();
    let t0 = clock.now();
    let now_s = move || clock.elapsed(t0).as_secs_f64();
    if driver_name != "sim" && config.home != Home::None {
        // Real servos: move to the start posture slowly, then leave them to the clients.
        let targets: Vec<JointTarget> = motor
            .driver()
            .joints()
            .iter()
            .filter_map(|s| {
                let position = config.home.position(&s.name, s.lower, s.upper)?;
                Some(JointTarget {
                    joint: s.name.clone(),
                    command: JointCommand::Position {
                        position,
                        max_speed: config.home_speed.min(s.max_velocity),
                    },
                })
            })
            .collect();
        let goal = JointGoal {
            client: HOME_CLIENT.into(),
            priority: 0,
            targets,
        };
        motor
            .submit(&goal, now_s())
            .context("moving to the start posture")?;
        motor.release(
            &JointRelease {
                client: HOME_CLIENT.into(),
                joints: vec![],
            },
            now_s(),
        )?;
    }
    tracing::info!(
        driver = driver_name,
        joints,
        urdf = %urdf.display(),
        home = ?config.home,
        "joint_motor ready: {} at {} Hz, goals on {}",
        topics::BODY_JOINT_STATES.name(),
        config.rate_hz,
        topics::BODY_JOINT_GOAL.name()
    );
    let motor = Arc::new(Mutex::new(motor));
    let counters = bus.counters().clone();

    let handler_motor = motor.clone();
    let handler_counters = counters.clone();
    let handler_now_s = now_s.clone();
    let refusal_log = Arc::new(Mutex::new(RateLimiter::new(Duration::from_secs(1))));
    let _service = bus
        .serve(&topics::BODY_JOINT_GOAL, move |req: m::JointGoal| {
            let motor = handler_motor.clone();
            let counters = handler_counters.clone();
            let refusal_log = refusal_log.clone();
            let now_s = handler_now_s.clone();
            async move {
                let reply = handle_goal(&motor, &req, now_s);
                if reply.accepted {
                    counters.incr(if req.release { "releases" } else { "goals_accepted" });
                    if !reply.preempted.is_empty() {
                        tracing::info!(
                            client = %req.client,
                            priority = req.priority,
                            "took {:?} from a lower-priority owner",
                            reply.preempted
                        );
                    }
                } else {
                    counters.incr(bus::refusal_counter(reply.refusal));
                    #[expect(
                        clippy::disallowed_methods,
                        reason = "the log limiter paces what a person reads, on the wall"
                    )]
                    let allowed = refusal_log
                        .lock()
                        .ok()
                        .and_then(|mut l| l.allow(Instant::now()));
                    if let Some(suppressed) = allowed {
                        tracing::info!(client = %req.client, suppressed, "refused a goal: {}", reply.detail);
                    }
                }
                Ok(reply)
            }
        })
        .await?;

    let states = bus.publisher(&topics::BODY_JOINT_STATES).await?;
    // Missed ticks are skipped.
    let mut tick = bus
        .clock()
        .interval(Duration::from_secs_f64(1.0 / config.rate_hz));
    let mut read_log = RateLimiter::new(Duration::from_secs(1));
    let mut keeper = match (driver_name, &config.state_dir) {
        ("sim", Some(dir)) => Some(crate::kept::Keeper::new(dir)),
        _ => None,
    };
    // The driver's own counters (the neck's clamped goals) and what it has to tell, each second.
    let mut report = bus.clock().interval(Duration::from_secs(1));
    loop {
        tokio::select! {
            biased;
            _ = shutdown.wait() => break,
            _ = report.tick() => {
                let (totals, warnings) = match motor.lock() {
                    Ok(mut m) => {
                        let d = m.driver_mut();
                        (d.counters(), d.take_warnings())
                    }
                    Err(_) => anyhow::bail!("the joint motor lock is poisoned"),
                };
                for (name, total) in totals {
                    counters.counter(name).store(total, std::sync::atomic::Ordering::Relaxed);
                }
                for w in warnings {
                    tracing::warn!("{w}");
                }
            }
            _ = tick.tick() => {
                let read = match motor.lock() {
                    Ok(mut m) => m.states(now_s()),
                    Err(_) => anyhow::bail!("the joint motor lock is poisoned"),
                };
                match read {
                    Ok(mut msg) => {
                        msg.driver = driver_name.to_owned();
                        if let Some(k) = keeper.as_mut() {
                            k.offer(&msg, bus.clock().now());
                        }
                        states.publish(&mut msg).await?;
                    }
                    Err(e) => {
                        counters.incr("read_errors");
                        #[expect(
                            clippy::disallowed_methods,
                            reason = "the log limiter paces what a person reads, on the wall"
                        )]
                        let allowed = read_log.allow(Instant::now());
                        if let Some(suppressed) = allowed {
                            tracing::warn!(suppressed, "could not read the joints: {e}");
                        }
                    }
                }
            }
        }
    }
    tracing::info!("stopped");
    Ok(())
}

/// One `body/joint_goal` request against the motor: the reply, accepted or refused. `now_s` is
/// read once the motor is locked, so that the driver's clock never goes backwards between
/// requests and the states loop.
pub fn handle_goal(
    motor: &Mutex<JointMotor>,
    req: &m::JointGoal,
    now_s: impl Fn() -> f64,
) -> m::JointGoalReply {
    let request = match bus::request_from_msg(req) {
        Ok(r) => r,
        Err(e) => return bus::refused(&e),
    };
    let Ok(mut motor) = motor.lock() else {
        return bus::refused(&crate::JointError::Bus(
            "the joint motor lock is poisoned".into(),
        ));
    };
    let now_s = now_s();
    match request {
        Request::Goal(goal) => match motor.submit(&goal, now_s) {
            Ok(preempted) => bus::accepted(&preempted),
            Err(e) => bus::refused(&e),
        },
        Request::Release(release) => match motor.release(&release, now_s) {
            Ok(freed) => m::JointGoalReply {
                accepted: true,
                detail: format!("released {freed:?}"),
                ..Default::default()
            },
            Err(e) => bus::refused(&e),
        },
    }
}

/// The `joint_motor` component.
#[derive(Debug)]
pub struct JointMotorComponent;

impl interfaces::node::Component for JointMotorComponent {
    const NAME: &'static str = "joint_motor";
    const ABOUT: &'static str = "Loki's joints on the bus: publishes body/joint_states at --rate-hz (every \
        joint's position, velocity and owner) and serves body/joint_goal (position or \
        velocity goals, refused with the joint, the limit and the owner when they break \
        a limit or another client owns the joint). Drivers: `sim` (no hardware) or \
        `dynamixel` (Protocol 2.0 servos on a serial port).";
    type Config = Config;
    type Prepared = Prepared;

    fn interface(_: &Config) -> Interface {
        interface()
    }

    fn prepare(config: Config) -> anyhow::Result<Prepared> {
        prepare(config)
    }

    async fn run(bus: Bus, prepared: Prepared, shutdown: Shutdown) -> anyhow::Result<()> {
        run(bus, prepared, shutdown).await
    }
}

#[cfg(test)]
mod tests;
