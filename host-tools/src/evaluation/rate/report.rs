//! The rate report: the tables `host-tools rate` prints and writes
//! (`rate.md`), one CSV row per build, encoding and stage (`rate.csv`), and
//! everything as JSON (`rate.json`).
use super::{BuildBudget, Cost};
use std::fmt::Write as _;

fn ms(us: f64) -> String {
    format!("{:.2}", us / 1000.0)
}

/// The markdown tables.
pub fn markdown(builds: &[BuildBudget], practical: f64) -> String {
    let mut s = String::new();
    for b in builds {
        let _ = writeln!(
            s,
            "{} (P = {}): a line of {}, read with a calibration of {} zone(s): {}",
            b.name, b.pixels, b.scene, b.zones, b.calibration
        );
    }
    let _ = writeln!(
        s,
        "\n## Line budget per stage (instructions exact from QEMU; cycles: Cortex-M4 timings; ms at 80 MHz)\n"
    );
    let _ = writeln!(
        s,
        "| build | encoding | stage | instructions/line | cycles/line | ms/line |\n|---|---|---|---|---|---|"
    );
    for b in builds {
        for e in &b.encodings {
            for (stage, c) in e.stages.iter().chain([("total".to_string(), e.compute)].iter()) {
                let _ = writeln!(
                    s,
                    "| {} (P = {}) | {} | {} | {:.0} | {:.0} | {} |",
                    b.name,
                    b.pixels,
                    e.encoding,
                    stage,
                    c.instructions,
                    c.cycles,
                    ms(c.us())
                );
            }
        }
    }
    let _ = writeln!(
        s,
        "\n## Which stage limits the line rate (link at the practical {practical} packets/ms; theoretical 19)\n"
    );
    let _ = writeln!(
        s,
        "| build | encoding | acquisition ms | correction in series ms (largest frame's us; frames over their settle) | compute ms (share of acquisition, w/o correction) | bytes/line | packets/line | link ms @19 / @{practical} | limit | lines/s |\n|---|---|---|---|---|---|---|---|---|---|"
    );
    for b in builds {
        for e in &b.encodings {
            let _ = writeln!(
                s,
                "| {} (P = {}) | {} | {} | {} ({:.0}; {} of {}) | {} ({:.0} %) | {} | {} | {} / {} | {} | {:.1} |",
                b.name,
                b.pixels,
                e.encoding,
                ms(b.acquisition.line_us),
                ms(e.correction_in_series_us),
                e.largest_frame_us,
                e.overlapped_frames.1,
                e.overlapped_frames.0,
                ms(e.compute.us()),
                100.0 * e.compute_share,
                e.traffic.bytes,
                e.traffic.packets,
                ms(e.link_us.0),
                ms(e.link_us.1),
                e.limit,
                1e6 / e.period_us
            );
        }
    }
    let _ = writeln!(
        s,
        "\n## Acquisition per line (derived from the firmware's settings; overhead assumed; the frames the device takes of this line: a frame that saturates is taken again at each shorter exposure while it saturates, with a dark frame at each)\n"
    );
    let _ = writeln!(
        s,
        "| build | frames | settle us | flush us | readout us | assumed ADC/DMA overhead us/frame | line ms (derived only) | had nothing saturated, ms | CPU free ms |\n|---|---|---|---|---|---|---|---|---|"
    );
    for b in builds {
        let a = &b.acquisition;
        let _ = writeln!(
            s,
            "| {} | {} | {:.0} | {:.1} | {:.1} | {:.0} | {} ({}) | {} | {} |",
            b.name,
            a.frames.describe(),
            a.settle_us,
            a.flush_us,
            a.readout_us,
            a.assumed_overhead_us,
            ms(a.line_us),
            ms(a.line_derived_us),
            ms(a.long_only_us),
            ms(a.cpu_free_us)
        );
    }
    let _ = writeln!(s, "\n## Sigma16 against the estimate's uncertainty (this line, decoded as the host does)\n");
    let _ = writeln!(
        s,
        "| build | max error / uncertainty | RMS error / uncertainty | points as Sigma16 | points sent alone as f32 |\n|---|---|---|---|---|"
    );
    for b in builds {
        let q = &b.sigma16;
        let _ = writeln!(
            s,
            "| {} | {:.5} | {:.5} | {} | {} |",
            b.name, q.max_ratio, q.rms_ratio, q.sigma16_points, q.f32_fallback_points
        );
    }
    s
}

/// One CSV row per build, encoding and stage.
pub fn csv(builds: &[BuildBudget]) -> String {
    let mut s = String::from("build,pixels,encoding,stage,instructions,cycles,us\n");
    for b in builds {
        for e in &b.encodings {
            for (stage, c) in e.stages.iter().chain([("total".to_string(), e.compute)].iter()) {
                let Cost { instructions, cycles } = *c;
                let _ =
                    writeln!(s, "{},{},{},{stage},{instructions},{cycles},{:.3}", b.name, b.pixels, e.encoding, c.us());
            }
        }
    }
    s
}
