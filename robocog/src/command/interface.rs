//! `robocog interface list | show | export`: the ROS 2 definitions of robocog's messages, as
//! `ros2 interface` shows a ROS 2 system's.
//!
//! The definitions are written from the Rust types (`ros_msgs`); they are what the recordings'
//! schemas hold, and what a ROS 2 tool needs to decode a robocog payload.

use std::io::Write;
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    pub verb: Verb,
}

#[derive(Debug, clap::Subcommand)]
pub enum Verb {
    /// Every message type with its ROS 2 name, or why ROS 2 cannot describe it.
    List {
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// The full ROS 2 definition of a type, with the messages it uses (as MCAP's `ros2msg`
    /// schemas and rosbag2 hold it). TYPE is a robocog type (`robocog.body.JointStates`) or a
    /// ROS 2 name (`robocog_msgs/msg/JointStates`).
    Show {
        #[arg(value_name = "TYPE")]
        type_name: String,
        /// Print its RIHS01 type hash (REP 2011) instead.
        #[arg(long)]
        hash: bool,
    },
    /// Write the `robocog_msgs` ROS 2 interface package (one `.msg` per message, with its
    /// package.xml and CMakeLists.txt) under DIR, for `colcon build`.
    Export {
        #[arg(value_name = "DIR")]
        dir: PathBuf,
    },
    /// Print the Python classes of every message type (the source of `python/robocog/msg.py`).
    Python,
}

pub fn execute(args: Args) -> anyhow::Result<i32> {
    let defs = ros_msgs::definitions();
    match args.verb {
        Verb::Python => {
            let src = ros_msgs::python::module()
                .map_err(|why| anyhow::anyhow!("no Python form: {why}"))?;
            out!("{src}");
            Ok(0)
        }
        Verb::List { json } => {
            if json {
                let all: Vec<serde_json::Value> = defs
                    .types()
                    .map(|(ty, r)| match r {
                        Ok(name) => serde_json::json!({
                            "type": ty,
                            "ros2": name,
                            "rihs01": defs.rihs01(ty).unwrap_or_default(),
                        }),
                        Err(why) => serde_json::json!({"type": ty, "ros2": null, "why": why}),
                    })
                    .collect();
                out!("{}", serde_json::Value::Array(all));
                return Ok(0);
            }
            let (mut ok, mut not) = (0, 0);
            for (ty, r) in defs.types() {
                match r {
                    Ok(name) => {
                        ok += 1;
                        out!("{ty:<40} {name}");
                    }
                    Err(why) => {
                        not += 1;
                        out!("{ty:<40} (no ROS 2 definition: {why})");
                    }
                }
            }
            out!("{ok} types with a ROS 2 definition, {not} without");
            Ok(0)
        }
        Verb::Show { type_name, hash } => {
            let robocog_type = defs
                .types()
                .find(|(ty, r)| *ty == type_name || r.as_ref().is_ok_and(|n| *n == type_name))
                .map(|(ty, _)| ty);
            let Some(ty) = robocog_type else {
                eprintln!("error: no message type {type_name:?} (see `robocog interface list`)");
                return Ok(2);
            };
            let shown = if hash {
                defs.rihs01(ty)
            } else {
                defs.full_definition(ty)
            };
            match shown {
                Ok(text) => {
                    out!("{}", text.trim_end());
                    Ok(0)
                }
                Err(why) => {
                    eprintln!("{ty} has no ROS 2 definition: {why}");
                    Ok(1)
                }
            }
        }
        Verb::Export { dir } => {
            let n = defs.export(&dir).map_err(|e| {
                anyhow::anyhow!("cannot write the package under {}: {e}", dir.display())
            })?;
            eprintln!(
                "wrote {n} messages to {}",
                dir.join(ros_msgs::msgdef::PACKAGE).display()
            );
            Ok(0)
        }
    }
}
