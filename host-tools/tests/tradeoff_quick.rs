//! The reduced configuration of `host-tools tradeoff` runs in the test
//! command, so the report cannot rot: the command succeeds, writes its four
//! files, and what it measured is sane (no timing assertions).
use std::process::Command;

#[test]
fn tradeoff_quick_runs_and_is_sane() {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_host-tools"))
        .args(["tradeoff", "--quick", "--out"])
        .arg(dir.path())
        .current_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "tradeoff --quick failed:\n{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    // Progress is for terminals: a piped stderr gets none of it.
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains('\r') && !stderr.contains('\u{1b}'), "progress drawn on a pipe: {stderr:?}");
    for f in ["tradeoff.md", "tradeoff.json", "tradeoff.svg", "tradeoff.png"] {
        let len = std::fs::metadata(dir.path().join(f)).map(|m| m.len()).unwrap_or(0);
        assert!(len > 500, "{f} missing or nearly empty ({len} bytes)");
    }
    let png = std::fs::read(dir.path().join("tradeoff.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    let svg = std::fs::read_to_string(dir.path().join("tradeoff.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.contains("Pareto front"));

    let j: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("tradeoff.json")).unwrap()).unwrap();
    let rows = j["rows"].as_array().unwrap();
    let row = |id: &str| rows.iter().find(|r| r["id"] == id).unwrap_or_else(|| panic!("row {id} missing"));
    for id in [
        "interpolation",
        "pseudo-inverse",
        "wiener-patent16",
        "wiener-dense",
        "wiener-wrong-range",
        "wiener-ggx",
        "fit-cond1",
        "fit-cond2",
        "fit-cond2-more",
        "clustered-k1",
        "clustered-k4",
        "clustered-k8",
        "log-wiener-dense",
        "wiener-patent16-q15",
        "wiener-dense-q15",
    ] {
        let r = row(id);
        for key in ["rmse", "nrmse", "max_abs_error", "host_seconds_per_point"] {
            let x = r[key].as_f64().unwrap_or(f64::NAN);
            assert!(x.is_finite() && x > 0.0, "{id}.{key} = {x}");
        }
    }
    let rmse = |id: &str| row(id)["rmse"].as_f64().unwrap();
    // The patent's ordering: cond 1 worst, cond 2 best, Wiener between.
    assert!(rmse("fit-cond1") > rmse("wiener-patent16") && rmse("wiener-patent16") > rmse("fit-cond2"));
    // A wrong prior costs accuracy; the K = 1 piecewise estimator is the plain
    // Wiener of the same prior (same selection-free matrix).
    assert!(rmse("wiener-wrong-range") > rmse("wiener-patent16"));
    assert!((rmse("clustered-k1") - rmse("wiener-dense")).abs() < 1e-9);
    // Q15 changes the estimates only at the 1e-4 level.
    let q = row("wiener-patent16-q15");
    assert!(q["vs_f64"].as_f64().unwrap() < 1e-3, "{q}");
    assert!((rmse("wiener-patent16-q15") - rmse("wiener-patent16")).abs() < 1e-2 * rmse("wiener-patent16"));
    // Something is on the Pareto front, and the front is consistent.
    let front: Vec<&serde_json::Value> = rows.iter().filter(|r| r["pareto"] == true).collect();
    assert!(!front.is_empty());
    for a in &front {
        for b in rows {
            let (ta, ea) = (a["host_seconds_per_point"].as_f64().unwrap(), a["rmse"].as_f64().unwrap());
            let (tb, eb) = (b["host_seconds_per_point"].as_f64().unwrap(), b["rmse"].as_f64().unwrap());
            assert!(!(tb <= ta && eb <= ea && (tb < ta || eb < ea)), "{} dominates Pareto row {}", b["id"], a["id"]);
        }
    }
    // Zones and LED counts are there and finite; more zones never cost flash less.
    let zones = j["zones"].as_array().unwrap();
    assert_eq!(zones.len(), 2);
    assert!(zones[1]["flash_bytes_f32"].as_u64() > zones[0]["flash_bytes_f32"].as_u64());
    assert!(zones.iter().all(|z| z["rmse"].as_f64().is_some_and(f64::is_finite)));
    let leds = j["leds"].as_array().unwrap();
    assert!(leds.iter().any(|l| l["m"] == 3) && leds.iter().any(|l| l["m"] == 7));
    assert!(leds.iter().all(|l| l["rmse"].as_f64().is_some_and(f64::is_finite)));
    // The target section says where it stands, whatever the numbers.
    assert!(!j["target"]["verdict"].as_str().unwrap().is_empty());
    assert!(stdout.contains("| id | estimator | RMSE"));
}
