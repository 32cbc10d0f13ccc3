//! The viewer: a robocog namespace's live topics, logged to rerun.
//!
//! # Concepts
//! - **Samples in, entities out.** Every sample of the namespace (or of the topics given) is
//!   decoded by the type name its encoding carries, through the one registry of `interfaces`, and
//!   turned by [`mapping::Mapper`] into rerun entities with the archetype that fits (a plain
//!   function of the sample, unit-testable without a bus or a viewer). A type this build does not
//!   know, or a payload that does not decode, is listed once, counted and skipped; the rest keeps
//!   logging.
//! - **Entity tree = frame tree.** rerun composes each entity's transform with its parents', so the
//!   robot is logged as the URDF's link tree: `world/robot/base_footprint/.../<link>`, each link's
//!   [`rerun::Transform3D`] being its joint's `parent_T_child(q)` from `body/joint_states` (rerun
//!   composes them, as `tf` does). Loki's `base_footprint` is the `world` origin (the touch game's
//!   scene). The head camera's images hang under its optical-frame link with a
//!   [`rerun::Pinhole`] (optical frame: z forward, x right, y down), so they show in 3D where the
//!   camera looks and the tracker's window is drawn on the image.
//! - **Units.** Metres and radians in 3D, as on the bus. The Nao field is logged in metres too
//!   (the bus has millimetres), in 3D at `field3d/**` (x towards the opponent goal, y left, z up),
//!   and in 2D at `field2d/**` with the y axis flipped (`(x, -y)`), because a 2D view draws y
//!   downwards: the field then reads as seen from above with our goal on the left.
//! - **Time.** Each sample is logged on the `stamp` timeline at its header stamp (the receipt time
//!   when the stamp is 0), so replayed and live data line up; rerun's own `log_time` is the
//!   receipt.
//! - **Never slows the robot.** The bus callback only copies the sample into a bounded queue
//!   ([`intake::Intake`]); a full queue drops the sample, counted per topic
//!   (`view_dropped/<topic>`), and the publishers never wait for rerun.
//!
//! # Entities
//! | topic | entity | archetype |
//! |---|---|---|
//! | `vision/rgbd` | `<camera link>/camera`, `…/camera/rgb`, `…/camera/depth` | Pinhole, Image, DepthImage |
//! | `body/joint_states` | `world/robot/…/<link>` (+ `…/collision/<i>` once) | Transform3D (+ Boxes3D, Cylinders3D, Capsules3D, Ellipsoids3D) |
//! | `vision/ball` | `world/ball`, `world/ball/trajectory`, `<camera>/camera/ball_window` | Points3D, LineStrips3D, Boxes2D |
//! | `sim/ball`, `sim/ball_truth` | `world/sim/ball` | Points3D |
//! | `body/reach`, `body/reach_status` | `world/reach/<part>/{goal,target,tip}`, `log/reach` | Points3D, TextLog |
//! | `nao/world_model`, `nao/local_model`, `sim/field_truth` | `field2d/**`, `field3d/**` | Points, Arrows, LineStrips |
//! | `dr/changes` (+ a `dr/snapshot` call) | `dr/nodes/<node>` (world pose), `dr/edges`, `log/dr` | Transform3D, Points3D, LineStrips3D, TextLog |
//! | `executive/transitions`, `executive/log` | `log/executive/<machine>`, `log/game` | TextLog |
//! | `speech/*`, `game/command`, `game/answer` | `log/speech/*`, `log/dialog/*` | TextLog |
//! | `speech/listening` | `hearing/<array>/{beam,her,someone_else}_azimuth_deg` | Scalars |
//! | every topic | `stats/{rate_hz,latency_ms,thinned,dropped}/<topic>` | Scalars |

pub mod blueprint;
pub mod component;
pub mod intake;
pub mod mapping;
