//! What an estimator costs on the device per point, counted exactly: the
//! QEMU firmware measures a line with a demo calibration of each kind while
//! `scripts/qemu-icount.sh` counts every instruction of the per-point
//! estimation path (`Calibration::estimate_pixel` and what it calls: matrix
//! selection, the kernel, cluster selection, the scale and the out-of-prior
//! statistic) and of the kernel alone.
use anyhow::{Context, ensure};
use serde::Serialize;
use std::path::Path;

/// One estimator's exact per-point cost.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DeviceCost {
    /// The demo estimator (`qemu --demo-estimator`).
    pub estimator: String,
    /// Instructions of the kernel (`point_kernel`) per point.
    pub kernel: u64,
    /// Instructions of the whole estimation path per point (median over the
    /// line's points; they differ only where cluster selection branches).
    pub path_median: u64,
    /// Largest path count over the points.
    pub path_max: u64,
}

/// Parses the script's output lines.
pub fn parse(estimator: &str, text: &str) -> anyhow::Result<DeviceCost> {
    let kernel = text
        .lines()
        .find_map(|l| l.strip_prefix("kernel: ")?.split_whitespace().next()?.parse().ok())
        .context("no `kernel:` line in qemu-icount.sh's output")?;
    let path = text
        .lines()
        .find(|l| l.starts_with("per-point estimation path"))
        .context("no estimation-path line in qemu-icount.sh's output")?;
    let field = |name: &str| -> anyhow::Result<u64> {
        let rest = path.split(&format!("{name} ")).nth(1).with_context(|| format!("no {name} in {path:?}"))?;
        rest.split(|c: char| !c.is_ascii_digit())
            .next()
            .unwrap_or("")
            .parse()
            .with_context(|| format!("{name} in {path:?}"))
    };
    Ok(DeviceCost { estimator: estimator.into(), kernel, path_median: field("median")?, path_max: field("max")? })
}

/// Runs `scripts/qemu-icount.sh 1 ESTIMATOR` in `root` for each estimator.
pub fn measure(root: &Path, estimators: &[&str]) -> anyhow::Result<Vec<DeviceCost>> {
    let script = root.join("scripts/qemu-icount.sh");
    ensure!(script.exists(), "{} not found (run from the repository)", script.display());
    estimators
        .iter()
        .map(|e| {
            let out = std::process::Command::new("bash")
                .arg(&script)
                .args(["1", e])
                .current_dir(root)
                .output()
                .with_context(|| format!("running {}", script.display()))?;
            ensure!(
                out.status.success(),
                "{} 1 {e} failed: {}",
                script.display(),
                String::from_utf8_lossy(&out.stderr)
            );
            parse(e, &String::from_utf8_lossy(&out.stdout))
        })
        .collect()
}

/// The markdown table, each path relative to the first row's (plain Wiener).
pub fn markdown(costs: &[DeviceCost]) -> String {
    let base = costs.first().map_or(1, |c| c.path_median.max(1)) as f64;
    let mut s = String::from(
        "| estimator | kernel (instr./point) | estimation path (median, max) | path vs first row |\n|---|---|---|---|\n",
    );
    for c in costs {
        s.push_str(&format!(
            "| {} | {} | {}, {} | {:.3} x |\n",
            c.estimator,
            c.kernel,
            c.path_median,
            c.path_max,
            c.path_median as f64 / base
        ));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scripts_lines_are_read_and_missing_ones_refused() {
        let text = "instructions per call (count x calls): 696x32\nkernel: 696 instructions per point, every call (n x m = 567 multiply-accumulates)\n\
                    instructions per multiply-accumulate: 1.228\nper-point estimation path (scale-free): min 900, median 904, max 910, mean 904.5 instructions\n";
        let c = parse("scale-free", text).unwrap();
        assert_eq!((c.kernel, c.path_median, c.path_max), (696, 904, 910));
        assert!(parse("x", "kernel: 696 instructions\n").is_err());
        let md = markdown(&[DeviceCost { path_median: 756, ..c.clone() }, c]);
        assert!(md.contains("1.196 x"), "{md}");
    }
}
