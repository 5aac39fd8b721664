//! The report as markdown (printed and written) and JSON.
use super::Report;
use std::fmt::Write;

fn sci(x: f64) -> String {
    if x.is_finite() { format!("{x:.2e}") } else { "-".into() }
}

/// The whole report as markdown.
pub fn markdown(r: &Report) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Accuracy against time (host-tools tradeoff{})\n", if r.quick { " --quick" } else { "" });
    let _ = writeln!(
        s,
        "Patent profile: m = {} LEDs, n = {} bins, {} test points (Table 4's 120 BRDFs x {} noise draws, {} % noise); priors: {}. RMS of the truth {:.3}.\n",
        r.m,
        r.n,
        r.points,
        r.draws,
        r.noise_rel * 100.0,
        r.prior_samples.iter().map(|(k, v)| format!("{k} {v}")).collect::<Vec<_>>().join(", "),
        r.rms_true
    );
    let _ = writeln!(
        s,
        "| id | estimator | RMSE | NRMSE | host s/point | device instr/point | device cycles (est.) | device us @80 MHz | flash B/zone | vs f64 | Pareto | cost |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|---|");
    let mut rows = r.rows.clone();
    rows.sort_by(|a, b| a.host_seconds_per_point.total_cmp(&b.host_seconds_per_point));
    for x in &rows {
        let (di, dc, du) = x.device.as_ref().map_or(("-".into(), "-".into(), "-".into()), |d| {
            (format!("{:.0}", d.instructions), format!("{:.0}", d.cycles), format!("{:.2}", d.seconds_at_80mhz * 1e6))
        });
        let _ = writeln!(
            s,
            "| {} | {} | {:.4} | {:.4} | {} | {} | {} | {} | {} | {} | {} | {} |",
            x.id,
            x.label,
            x.rmse,
            x.nrmse,
            sci(x.host_seconds_per_point),
            di,
            dc,
            du,
            x.flash_bytes.map_or("-".into(), |b| b.to_string()),
            x.vs_f64.map_or("-".into(), |v| format!("{v:.1e}")),
            if x.pareto { "**yes**" } else { "" },
            x.cost
        );
    }
    let t = &r.target;
    let _ = writeln!(s, "\n## Accuracy target (RMSE <= condition 2 at >= 1e5 x its speed)\n");
    let _ = writeln!(
        s,
        "Condition 2: RMSE {:.4}, {:.2} us per point on this host. Best linear-cost row: {} (RMSE {:.4}, {:.2e} x faster than condition 2).",
        t.cond2_rmse,
        t.cond2_seconds_per_point * 1e6,
        t.best_linear_id,
        t.best_linear_rmse,
        t.best_linear_speedup
    );
    if let (Some(d), Some(id)) = (t.reaching_device_vs_host_fit, &t.reaching_id) {
        let _ = writeln!(
            s,
            "On the device, {id} takes {:.1} us per point (80 MHz, cycle estimate): {:.2} x the time the condition-2 fit takes per point on this host (a fit on the M4 itself would take far longer).",
            t.cond2_seconds_per_point / d * 1e6,
            1.0 / d
        );
    }
    let _ = writeln!(s, "\n**{}**", t.verdict);

    if let Some(k) = &r.kernels {
        let _ = writeln!(s, "\n## Device kernels (QEMU b-l475e-iot01a, exact instruction counts; `{}`)\n", k.command);
        let _ = writeln!(
            s,
            "| kernel | instructions/point | instr per MAC ({} MACs) | cycles/point (est.) | us @80 MHz |",
            k.n * k.m
        );
        let _ = writeln!(s, "|---|---|---|---|---|");
        let macs = (k.n * k.m) as f64;
        for (name, i, c) in [
            ("f32 mat-vec (VLDM/VMLA/VSTM asm, m = 7)", k.f32_instructions, k.f32_cycles),
            ("Q15 mat-vec (SMLAD asm, m = 7)", k.q15_instructions, k.q15_cycles),
            ("Q15: quantise one point's readings", k.quantise_v_instructions, k.quantise_v_cycles),
            ("Q15: accumulators to f32 (81 bins)", k.dequantise_instructions, k.dequantise_cycles),
            ("affine constant term (81 adds)", k.offset_instructions, k.offset_cycles),
        ] {
            let _ = writeln!(s, "| {name} | {i:.0} | {:.3} | {c:.0} | {:.2} |", i / macs, c / 80.0);
        }
        let sel: Vec<String> = k
            .select
            .iter()
            .filter(|x| [1, 2, 4, 8, 16].contains(&x.0))
            .map(|(kk, i, c)| format!("K={kk}: {i:.0} instr / {c:.0} cycles"))
            .collect();
        let _ = writeln!(s, "| cluster selection (m = 7) | {} | | | |", sel.join("; "));
        let _ = writeln!(
            s,
            "\nLoad-time quantisation of one W to Q15: {:.0} instructions. Bit-exact against the host: {} ({}).",
            k.quantise_w_instructions,
            if k.bit_exact { "yes" } else { "NO" },
            k.compared
        );
    }

    let sp = &r.speed;
    let _ =
        writeln!(s, "\n## Host batch speed ({} points, n = {}, m = {}, f32; {})\n", sp.points, sp.n, sp.m, sp.numpy);
    let _ = writeln!(s, "| what | threads | best [s] | median [s] | ns/point |");
    let _ = writeln!(s, "|---|---|---|---|---|");
    for t in &sp.timings {
        let _ = writeln!(
            s,
            "| {} | {} | {:.4} | {:.4} | {:.1} |",
            t.what,
            t.threads.map_or("default".into(), |x| x.to_string()),
            t.best_s,
            t.median_s,
            t.best_s_per_point * 1e9
        );
    }
    let _ = writeln!(
        s,
        "\nPer thread count (rayon pool of t threads; numpy with OpenBLAS on t threads; floor = the machine's \
         bandwidth at t threads, the better of a STREAM-like copy and triad, over {} B per point: m readings in, \
         n values out, f32):\n",
        sp.bytes_per_point
    );
    let _ = writeln!(
        s,
        "| threads | host [points/s] | numpy [points/s] | host / numpy | copy / triad [GB/s] | floor [points/s] | host / floor |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    for t in &sp.per_threads {
        let bw = sp.bandwidth.iter().find(|b| b.threads == t.threads);
        let _ = writeln!(
            s,
            "| {} | {:.3e} | {} | {} | {} | {:.3e} | {:.2} |",
            t.threads,
            t.host_points_per_s,
            t.numpy_points_per_s.map_or("-".into(), |x| format!("{x:.3e}")),
            t.host_over_numpy.map_or("-".into(), |x| format!("{x:.2}")),
            bw.map_or("-".into(), |b| format!("{:.1} / {:.1}", b.copy_bytes_per_s / 1e9, b.triad_bytes_per_s / 1e9)),
            t.floor_points_per_s,
            t.host_over_floor
        );
    }
    let _ = writeln!(
        s,
        "\nThe kernel's arithmetic alone ({} points in L2, one thread): {:.3e} points/s ({:.1} ns per point).",
        super::speed::IN_CACHE_POINTS,
        sp.host_in_cache_points_per_s,
        1e9 / sp.host_in_cache_points_per_s
    );
    if let Some(x) = sp.host_over_numpy_1t {
        let _ = writeln!(
            s,
            "\nHost single thread / numpy single thread (time) = {x:.2} ({}).",
            if x <= 1.0 { "host at least as fast" } else { "host SLOWER" }
        );
    }
    if let Some(x) = sp.host_over_numpy_best {
        let _ = writeln!(s, "Host best / numpy best, any thread count (time) = {x:.2}.");
    }

    if !r.zones.is_empty() {
        let _ = writeln!(
            s,
            "\n## Zones along the line sensor (handheld geometry, 128 pixels, Wiener with the dense prior)\n"
        );
        let _ = writeln!(s, "| Z | RMSE | worst pixel RMSE (pixel) | flash f32 [B] | flash Q15 [B] |");
        let _ = writeln!(s, "|---|---|---|---|---|");
        for z in &r.zones {
            let _ = writeln!(
                s,
                "| {} | {:.4} | {:.4} ({}) | {} | {} |",
                z.zones, z.rmse, z.worst_pixel_rmse, z.worst_pixel, z.flash_bytes_f32, z.flash_bytes_q15
            );
        }
    }
    if !r.leds.is_empty() {
        let _ = writeln!(s, "\n## Number of LEDs (same arc 33..57 deg, same test set)\n");
        let ids: Vec<String> = {
            let mut v: Vec<String> = Vec::new();
            for l in &r.leds {
                let base = if l.id.starts_with("clustered") { "clustered".to_string() } else { l.id.clone() };
                if !v.contains(&base) {
                    v.push(base);
                }
            }
            v
        };
        let _ = writeln!(
            s,
            "| m | {} |",
            ids.iter().map(|i| format!("{i} RMSE / s per point")).collect::<Vec<_>>().join(" | ")
        );
        let _ = writeln!(s, "|---|{}", "---|".repeat(ids.len()));
        let mut ms: Vec<usize> = r.leds.iter().map(|l| l.m).collect();
        ms.dedup();
        for m in ms {
            let cells: Vec<String> = ids
                .iter()
                .map(|id| {
                    r.leds
                        .iter()
                        .find(|l| l.m == m && (l.id == *id || (id == "clustered" && l.id.starts_with("clustered"))))
                        .map_or("-".into(), |l| format!("{:.4} / {}", l.rmse, sci(l.host_seconds_per_point)))
                })
                .collect();
            let _ = writeln!(s, "| {m} | {} |", cells.join(" | "));
        }
    }
    if !r.notes.is_empty() {
        let _ = writeln!(s, "\n## Notes\n");
        for n in &r.notes {
            let _ = writeln!(s, "- {n}");
        }
    }
    s
}
