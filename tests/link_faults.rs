//! The client and the simulated device over a faulty link (drops, repeats,
//! corruption and delays of bytes and frames, disconnects mid-provisioning and
//! mid-stream): a short seeded soak. The long one is the `link_soak` example:
//! `cargo run --release -p system-tests --example link_soak -- --frames 100000 --seed 1`.
use system_tests::link_faults::{FAULTS, FaultRates, SoakConfig, soak};

#[test]
fn a_faulty_link_loses_repeats_or_alters_nothing_unnoticed_and_the_client_recovers() {
    let r = soak(SoakConfig { frames: 3000, seed: 7, rates: FaultRates::SOAK });
    println!("{r}");
    assert_eq!(r.undetected, 0, "{r}");
    // The run met every kind of fault, on points too, and both outcomes of
    // provisioning under faults were checked.
    for (k, f) in FAULTS.iter().enumerate() {
        assert!(r.link.injected[k] > 0, "no {f:?} injected");
    }
    assert!(r.on_points.iter().sum::<u64>() > 0 && r.points_missing > 0 && r.points_duplicate > 0);
    assert!(r.link.request_faults > 0 && r.client.retries > 0 && r.client.resyncs > 0);
    assert!(r.provisionings > 0 && r.provision_completed > 0);
    assert!(r.recoveries > 0);
    // Detected means the host's accounting shows every fault that hit a point.
    assert_eq!(r.detected, r.on_points);
    // Every point asked for is accounted for: accepted or reported missing.
    assert_eq!(r.points_accepted + r.points_missing, r.points_expected);
}
