//! In-process transform lookup benchmark of the deep representation (no bus).
//!
//! What it measures is documented in [`world_model::bench`]; the `bench_dr` binary runs
//! the same figures and adds the bus round trip of the `dr/transform` service.
//!
//! Run: `cargo run --release -p world_model --example bench_dr_local [-- N]`
//! (N lookups per row, default 1,000,000). The last line is one JSON object.

use robot_model::RobotModel;
use world_model::bench::local_lookup_bench;

fn main() -> anyhow::Result<()> {
    let n: usize = std::env::args()
        .nth(1)
        .map(|s| s.parse())
        .transpose()?
        .unwrap_or(1_000_000);
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../models/loki.urdf");
    let model = RobotModel::from_urdf_file(path)?;
    let b = local_lookup_bench(&model, n)?;
    println!(
        "deep_representation bench_dr_local: {n} lookups per row, world -> left_fingertip ({} edges, 13 joints)",
        b.chain_edges
    );
    println!(
        "{:<30} {:>9} {:>9} {:>10} {:>9}",
        "measure", "p50 ns", "p99 ns", "mean ns", "max ns"
    );
    for r in b.rows() {
        println!(
            "{:<30} {:>9} {:>9} {:>10.1} {:>9}",
            r.name, r.p50, r.p99, r.mean, r.max
        );
    }
    println!(
        "(fork rows: {} runs each; checksum {:.3})",
        b.fork.count, b.checksum
    );
    println!(
        "{{\"transform_lookup_p50_ns\": {}, \"transform_lookup_p99_ns\": {}, \"transform_lookup_mean_ns\": {:.1}, \"transform_lookup_at_time_p50_ns\": {}, \"transform_lookup_at_time_p99_ns\": {}, \"fk13_p50_ns\": {}, \"fork_p50_ns\": {}, \"whatif_p50_ns\": {}, \"chain_edges\": {}, \"lookups\": {}, \"target_ns\": 1000}}",
        b.latest.p50,
        b.latest.p99,
        b.latest.mean,
        b.at_time.p50,
        b.at_time.p99,
        b.fk13.p50,
        b.fork.p50,
        b.whatif.p50,
        b.chain_edges,
        n
    );
    Ok(())
}
