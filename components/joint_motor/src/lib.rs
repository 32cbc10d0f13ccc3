//! The robot's joints (component `joint_motor`): one driver trait, the `sim` and `dynamixel`
//! drivers, joint ownership among several clients, and the Stewart-platform neck.
//!
//! # Concepts and units
//! - A **joint** is described by a [`JointSpec`]: name (as in the URDF), revolute (rad, rad/s,
//!   rad/s²) or prismatic (m, m/s, m/s²), position limits, maximum velocity and acceleration.
//! - A **driver** ([`JointDriver`], chosen by name with [`open_driver`]: `sim` or `dynamixel`)
//!   moves a list of joints. Goals ([`JointCommand`]) are a position with a maximum speed, or a
//!   velocity. A goal beyond a limit or for an unknown joint is refused with a typed
//!   [`JointError`] naming the joint and the limit; nothing is ever clamped silently.
//! - **Time** is always passed in (`now_s`, seconds on the caller's clock, non-decreasing): the
//!   component calls [`JointMotor::states`] at 100 Hz or more and publishes the result.
//!
//! # Ownership (several clients at once)
//! [`JointMotor`] puts a driver behind this rule:
//! 1. Every [`JointGoal`] carries a client id and a priority (0–255, default 0) and names its
//!    joints. A goal is accepted or refused as a whole.
//! 2. An accepted goal makes its client the **owner** of every joint it names, with the goal's
//!    priority, until the client releases the joint ([`JointRelease`]) or sends no goal naming
//!    it for longer than the lease time (`lease_s`, e.g. 1 s): a silent client loses its joints.
//! 3. A goal naming a joint owned (live lease) by another client is refused with
//!    [`JointError::Owned`] naming the joint, the owner and its priority — unless the goal's
//!    priority is **strictly higher**, in which case it takes the joint over (reported as
//!    [`Preempted`]). Equal priority never preempts: first come, first served.
//! 4. When a joint is freed (release or lapse) it holds its last position goal; a joint that was
//!    moving under a velocity goal is brought to rest (velocity 0, acceleration-limited).
//! 5. [`JointStates`] tells, per joint, the current owner.
//!
//! # Example
//! ```
//! use joint_motor::{JointCommand, JointGoal, JointMotor, JointSpec, JointTarget, open_driver};
//!
//! let joints = vec![JointSpec::revolute("elbow", 0.0, 2.0, 1.0, 5.0)];
//! let mut motor = JointMotor::new(open_driver("sim", joints, None)?, 1.0)?;
//! let goal = JointGoal {
//!     client: "reach".into(),
//!     priority: 0,
//!     targets: vec![JointTarget {
//!         joint: "elbow".into(),
//!         command: JointCommand::Position { position: 1.2, max_speed: 0.8 },
//!     }],
//! };
//! motor.submit(&goal, 0.0)?;
//! let states = motor.states(0.5)?; // called at 100 Hz by the component
//! assert_eq!(states.get("elbow").unwrap().owner, "reach");
//! let states = motor.states(3.0)?;
//! let elbow = states.get("elbow").unwrap();
//! assert!((elbow.position - 1.2).abs() < 1e-3);
//! assert_eq!(elbow.owner, ""); // "reach" was silent for more than the 1 s lease
//! # Ok::<(), joint_motor::JointError>(())
//! ```
//!
//! # Modules
//! - [`types`]: the library's serde structs (with `Option`); their CDR-safe bus mirrors are
//!   `interfaces::msg::body`, converted in [`bus`].
//! - [`sim`]: first-order joints with velocity and acceleration saturation.
//! - [`dynamixel`]: Dynamixel Protocol 2.0 codec, serial transport, X-series driver, TOML config.
//! - [`stewart`]: the neck's pitch/roll/yaw ↔ three prismatic leg lengths.
//! - [`neck`]: a driver wrapper presenting the three legs as pitch, roll and yaw joints.
//! - [`home`]: the start postures (`rest`: arms hanging beside the body, head slightly down).
//! - [`bus`]: conversions to and from the bus messages of `interfaces::msg::body` (one place).
//! - [`component`]: the `joint_motor` process (`body/joint_states`, `body/joint_goal`).
//! - `servo_sim` (tests, or feature `servo-sim`): a simulated X-series servo chain on a pty.

pub mod bus;
pub mod component;
pub mod driver;
pub mod dynamixel;
pub mod error;
pub mod home;
pub mod kept;
pub mod neck;
pub mod ownership;
#[cfg(any(test, feature = "servo-sim"))]
pub mod servo_sim;
pub mod sim;
pub mod stewart;
pub mod types;

pub use driver::{DriverKind, JointDriver, check_targets, open_driver};
pub use error::{JointError, LimitKind};
pub use ownership::{Arbiter, JointMotor, Lease, Preempted};
pub use types::{
    JointCommand, JointGoal, JointKind, JointRelease, JointSpec, JointState, JointStates,
    JointTarget, LinkStats,
};
