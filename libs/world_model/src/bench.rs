//! In-process benchmark of the scene graph, shared by the `bench_dr_local` example and the
//! `bench_dr` binary (which adds the bus round trip).
//!
//! [`local_lookup_bench`] loads a robot model into the touch-the-ball scene and measures
//! `SceneGraph::transform_ids(world, left_fingertip)`: the chain world -> loki -> base_footprint ->
//! base yaw/forward -> spine -> torso -> 11 left-arm joints -> fingertip. Before every lookup one of
//! the 13 chain joints gets a new value (not timed), so no result can be cached. Each lookup is
//! timed on its own with `Instant` (the timer's own cost, the "timer overhead" row, is included in
//! the figures). Rows: latest-state lookups, lookups "at time t" inside the edge histories
//! (interpolated), `Chain::fk` on the same 13 joints for comparison, `SceneGraph::fork()`, and a
//! whole what-if (fork, move a joint and the ball, evaluate the predicates of both graphs, diff).
//!
//! This module reads the monotonic clock (`Instant`); it is a measurement tool, not part of the
//! world model.
#![expect(
    clippy::disallowed_methods,
    reason = "a benchmark: it measures CPU work on the wall's monotonic clock"
)]

use std::hint::black_box;
use std::time::Instant;

use crate::error::Result;
use crate::graph::At;
use crate::predicates::{PredicateConfig, fork_report};
use crate::scenes;
use crate::types::Stamp;
use robot_model::RobotModel;

/// Order statistics of one measured quantity (ns).
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// What was measured.
    pub name: &'static str,
    /// Median (ns).
    pub p50: u64,
    /// 99th percentile (ns).
    pub p99: u64,
    /// Mean (ns).
    pub mean: f64,
    /// Maximum (ns).
    pub max: u64,
    /// Samples.
    pub count: usize,
}

/// Order statistics of `samples` (ns); an empty set gives zeros.
pub fn stats(name: &'static str, mut samples: Vec<u64>) -> Row {
    if samples.is_empty() {
        return Row {
            name,
            p50: 0,
            p99: 0,
            mean: 0.0,
            max: 0,
            count: 0,
        };
    }
    samples.sort_unstable();
    let pick = |q: f64| samples[((samples.len() as f64 - 1.0) * q).round() as usize];
    let mean = samples.iter().sum::<u64>() as f64 / samples.len() as f64;
    Row {
        name,
        p50: pick(0.50),
        p99: pick(0.99),
        mean,
        max: samples[samples.len() - 1],
        count: samples.len(),
    }
}

/// The figures of [`local_lookup_bench`].
#[derive(Debug, Clone)]
pub struct LocalBench {
    /// Lookups per lookup row.
    pub lookups: usize,
    /// Edges from `world` down to `left_fingertip`.
    pub chain_edges: usize,
    /// `transform_ids(world, left_fingertip, Latest)`.
    pub latest: Row,
    /// The same at a past time inside the histories.
    pub at_time: Row,
    /// `Chain::fk` on the 13 joints.
    pub fk13: Row,
    /// `SceneGraph::fork()`.
    pub fork: Row,
    /// Fork, two virtual actions, predicates of both graphs and their diff.
    pub whatif: Row,
    /// The cost of `Instant::now()` + `elapsed()` alone.
    pub timer_overhead: Row,
    /// Sum of results, so nothing is optimised away.
    pub checksum: f64,
}

impl LocalBench {
    /// Every row, in print order.
    pub fn rows(&self) -> [&Row; 6] {
        [
            &self.latest,
            &self.at_time,
            &self.fk13,
            &self.fork,
            &self.whatif,
            &self.timer_overhead,
        ]
    }
}

/// Runs the in-process benchmark with `n` lookups per row (the fork rows run `max(n / 1000,
/// 100)` times). `model` must be Loki (it needs `left_fingertip` and the `left_arm_13` chain).
pub fn local_lookup_bench(model: &RobotModel, n: usize) -> Result<LocalBench> {
    let n = n.max(1);
    let mut g = scenes::touch_the_ball(model, Stamp(0))?;
    let chain = model.body_part("left_arm_13")?;
    let joint_ids = chain
        .joint_names()
        .iter()
        .map(|j| g.joint_node(j))
        .collect::<Result<Vec<_>>>()?;
    let world = g.id("world")?;
    let tip = g.id("left_fingertip")?;
    let mut depth = 0;
    let mut cur = g.node_by_id(tip).and_then(|n| n.parent);
    while let Some(p) = cur {
        depth += 1;
        cur = g.node_by_id(p).and_then(|n| n.parent);
    }

    let mut overhead = Vec::with_capacity(n.min(100_000));
    for _ in 0..overhead.capacity() {
        let t0 = Instant::now();
        overhead.push(t0.elapsed().as_nanos() as u64);
    }
    let timer_overhead = stats("timer overhead", overhead);

    let value = |i: usize| ((i % 1000) as f64 * 0.001 - 0.5) * 0.8;
    let mut lat = Vec::with_capacity(n);
    let mut sink = 0.0;
    for i in 0..n {
        let j = joint_ids[i % joint_ids.len()];
        g.set_joint_id(j, value(i), Stamp(i as u64 + 1))?;
        let t0 = Instant::now();
        let t = black_box(&g).transform_ids(black_box(world), black_box(tip), At::Latest)?;
        lat.push(t0.elapsed().as_nanos() as u64);
        sink += t.translation.vector.x;
    }
    let latest = stats("transform_lookup (latest)", lat);

    let newest = n as u64;
    let window = (g.history_len() as u64).saturating_sub(2).max(1);
    let mut hist = Vec::with_capacity(n);
    for i in 0..n {
        let t = Stamp(newest.saturating_sub(i as u64 % window + 1));
        let t0 = Instant::now();
        let x = black_box(&g).transform_ids(world, tip, At::Time(black_box(t)));
        hist.push(t0.elapsed().as_nanos() as u64);
        sink += x.map(|x| x.translation.vector.y).unwrap_or(0.0);
    }
    let at_time = stats("transform_lookup (at time t)", hist);

    let mut q = [0.0; 13];
    let mut fk = Vec::with_capacity(n);
    for i in 0..n {
        q[i % 13] = value(i);
        let t0 = Instant::now();
        let t = chain.fk_unchecked(black_box(&q));
        fk.push(t0.elapsed().as_nanos() as u64);
        sink += t.translation.vector.z;
    }
    let fk13 = stats("Chain::fk (13 joints)", fk);

    let m = (n / 1000).max(100);
    let cfg = PredicateConfig::default();
    let (mut forks, mut whatifs) = (Vec::with_capacity(m), Vec::with_capacity(m));
    let ball_pose = crate::graph::translation(0.42, 0.2, 1.0);
    for i in 0..m {
        let t0 = Instant::now();
        let f = black_box(&g).fork();
        forks.push(t0.elapsed().as_nanos() as u64);
        sink += f.len() as f64;
        drop(f);
        let t0 = Instant::now();
        let mut f = g.fork();
        f.set_joint_id(joint_ids[2], -1.2, Stamp(n as u64 + 1))?;
        f.set_pose("ball", &ball_pose, Stamp(n as u64 + 1))?;
        let r = fork_report(&g, &f, &cfg)?;
        whatifs.push(t0.elapsed().as_nanos() as u64);
        sink += (r.facts.became_true.len() + i % 2) as f64;
    }
    Ok(LocalBench {
        lookups: n,
        chain_edges: depth,
        latest,
        at_time,
        fk13,
        fork: stats("fork()", forks),
        whatif: stats("fork + 2 actions + report", whatifs),
        timer_overhead,
        checksum: sink,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_pick_order_statistics() {
        let r = stats("x", (1..=100).rev().collect());
        assert_eq!((r.p50, r.p99, r.max, r.count), (51, 99, 100, 100));
        assert!((r.mean - 50.5).abs() < 1e-12);
        assert_eq!(stats("empty", Vec::new()).count, 0);
    }

    #[test]
    fn the_bench_runs_on_loki_and_measures_the_whole_chain() {
        let model = RobotModel::from_urdf_file(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../models/loki.urdf"
        ))
        .unwrap();
        let b = local_lookup_bench(&model, 200).unwrap();
        assert!(b.chain_edges >= 15, "{}", b.chain_edges);
        assert_eq!(b.latest.count, 200);
        assert!(b.latest.p50 > 0 && b.latest.p50 <= b.latest.p99);
        assert_eq!(b.fork.count, 100);
    }
}
