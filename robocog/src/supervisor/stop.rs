//! Stopping the graph: dependents before their dependencies, SIGTERM then SIGKILL after each
//! one's stop time-out, those on other machines through their agents.

use super::process::BoxFuture;
use super::remote::{Machines, agent_request, call_agent};
use super::{Child, State, say};
use crate::manifest::Manifest;
use interfaces::msg::agent::AgentAction;
use nix::sys::signal::{Signal, killpg};
use nix::unistd::Pid;
use std::collections::HashMap;
use std::time::Duration;

/// Stop every running child, dependents before their dependencies: SIGTERM to its process group,
/// then SIGKILL after its stop time-out. Finally SIGKILL every group, so nothing is left behind.
pub(super) async fn stop_all(
    manifest: &Manifest,
    children: &mut HashMap<String, Child>,
    machines: Option<&Machines>,
) {
    // Depth in the dependency graph: leaves (no dependents) stop first.
    let mut depth: HashMap<String, usize> = HashMap::new();
    if let Ok(order) = manifest.start_order() {
        for c in order {
            let d = c
                .depends_on
                .iter()
                .filter_map(|d| depth.get(d))
                .max()
                .map_or(0, |d| d + 1);
            depth.insert(c.name.clone(), d);
        }
    }
    let max_depth = depth.values().copied().max().unwrap_or(0);
    let mut groups = Vec::new();
    for level in (0..=max_depth).rev() {
        let mut waiting = Vec::new();
        let mut remote: Vec<BoxFuture> = Vec::new();
        for c in children.values_mut() {
            if depth.get(&c.spec.name).copied().unwrap_or(0) != level {
                continue;
            }
            if let Some(machine) = c.remote.clone() {
                // On another machine: its agent stops it (and says so when it has exited).
                let running = c.pid.take().is_some()
                    || matches!(c.state, State::Starting { .. } | State::Unreachable);
                if let (true, Some(ms)) = (running, machines) {
                    let mut request = agent_request(ms, AgentAction::Stop, c);
                    request.stop_timeout_ms = c.spec.stop_timeout.as_millis() as u64;
                    let wait = c.spec.stop_timeout + Duration::from_secs(6);
                    let bus = ms.bus.clone();
                    let name = c.spec.name.clone();
                    let reachable = ms.up.contains(&machine);
                    remote.push(Box::pin(async move {
                        if !reachable {
                            say(format!(
                                "cannot stop {name}: machine {machine} is out of reach (its agent stops it once the launcher has been gone a while)"
                            ));
                            return;
                        }
                        if let Err(e) = call_agent(&bus, &machine, &request, wait).await {
                            say(format!("cannot stop {name}: {e}"));
                        }
                    }));
                }
                continue;
            }
            if let Some(pid) = c.pid.take() {
                groups.push(pid);
                let _ = killpg(Pid::from_raw(pid as i32), Signal::SIGTERM);
                waiting.push((
                    c.spec.name.clone(),
                    pid,
                    c.spec.stop_timeout,
                    c.exit.clone(),
                ));
            }
        }
        let waits = waiting
            .into_iter()
            .map(|(name, pid, grace, exit)| async move {
                let Some(mut exit) = exit else { return };
                #[expect(
                    clippy::disallowed_methods,
                    reason = "a real process' stop time-out (SIGTERM, then SIGKILL), on the wall"
                )]
                let done = tokio::time::timeout(grace, async {
                    let _ = exit.wait_for(|s| s.is_some()).await.map(|_| ());
                })
                .await;
                if done.is_err() {
                    say(format!(
                        "{name} ignored SIGTERM for {:.1} s: SIGKILL",
                        grace.as_secs_f64()
                    ));
                    let _ = killpg(Pid::from_raw(pid as i32), Signal::SIGKILL);
                    #[expect(
                        clippy::disallowed_methods,
                        reason = "waits for a killed real process to be reaped, on the wall"
                    )]
                    let _ = tokio::time::timeout(Duration::from_secs(5), async {
                        let _ = exit.wait_for(|s| s.is_some()).await.map(|_| ());
                    })
                    .await;
                }
            });
        let remote = remote.into_iter().map(tokio::spawn).collect::<Vec<_>>();
        futures_join_all(waits).await;
        for r in remote {
            let _ = r.await;
        }
    }
    // Anything a component left in its group goes too.
    for pid in groups {
        let _ = killpg(Pid::from_raw(pid as i32), Signal::SIGKILL);
    }
    say("all components stopped");
}

async fn futures_join_all<F: std::future::Future<Output = ()> + Send + 'static>(
    futures: impl IntoIterator<Item = F>,
) {
    let handles: Vec<_> = futures.into_iter().map(tokio::spawn).collect();
    for h in handles {
        let _ = h.await;
    }
}
