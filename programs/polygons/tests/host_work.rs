//! Host work follows the machine's work: the simulator's own counts (`HostWork`) grow about
//! linearly with the triangles drawn, and a unit waiting for ring space costs one offer per
//! instant, not a retry per queued message (issue 10: the blocked-send churn that made 10,000
//! triangles on the paper's machine take 22.7 s).

use pxpl5_machine::{HostWork, Machine, Recorder, RunOptions};
use pxpl5_polygons::{Polygons, scenes};

fn config(name: &str) -> pxpl5_config::MachineConfig {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../machine-configs");
    pxpl5_config::load_file(&root.join(name)).expect("shipped config")
}

/// The host work of drawing `n` random triangles on the paper's machine.
fn work(n: usize) -> (HostWork, u64) {
    let cfg = config("pxpl5-1989.ron");
    let program = Polygons::new(scenes::random_scene(n, 7, 3.0));
    let r = Machine::new(&cfg, &program, RunOptions::default(), Recorder::default())
        .expect("builds")
        .run()
        .expect("runs");
    let units = u64::from(cfg.gp.count + cfg.renderer.count);
    (r.host, units)
}

#[test]
fn host_work_grows_linearly_and_a_blocked_sender_costs_one_offer_an_instant() {
    let (small, units) = work(1_000);
    let (large, _) = work(4_000);
    // The ring's queues do fill on this machine: the test exercises the waiting senders.
    assert!(large.refused_offers > 0, "{large:?}");
    for w in [small, large] {
        // At most one refused offer per waiting unit per pass over the units at an instant (a
        // pass repeats only when something moved).
        assert!(
            w.refused_offers <= units * w.instants,
            "{w:?}: more refused offers than units x instants"
        );
    }
    // Four times the triangles: about four times the instants (measured 3.52x) and offers
    // (5.04x). The offers grow a little faster: with more triangles more GPs wait for ring space
    // at once, and each waiting unit is offered again at every instant (O(1) each; waking it
    // only when its queue has room, issue 10's wake lists, is not built). The old churn cloned
    // every waiting message at every instant and grew 46x for 8x the work.
    let ratio = |a: u64, b: u64| b as f64 / a.max(1) as f64;
    let (instants, offers) = (
        ratio(small.instants, large.instants),
        ratio(small.offers, large.offers),
    );
    assert!(
        instants < 4.5 && offers < 6.0,
        "4x the triangles: {instants:.2}x the instants, {offers:.2}x the offers ({small:?} -> {large:?})"
    );
}
