//! Device cost of the kernels: exact instruction counts from QEMU and a cycle
//! estimate from the Cortex-M4 instruction timings, plus a bit-for-bit check
//! of the device's results against the host's.
//!
//! `scripts/kernel-bench.sh` builds `src/bin/kernel-bench.rs` and runs it in
//! QEMU (b-l475e-iot01a) with `-accel tcg,one-insn-per-tb=on -d exec,nochain`:
//! every executed instruction is one trace line with its address. The bench
//! calls `kernel_bench_mark` between the measured calls; here the trace is cut
//! at each execution of that function and the instructions of each segment
//! (the mark's own excluded, the call and return of the measured function
//! included) are counted and named by the `SEG` lines the firmware printed.
//!
//! # Cycle estimate (Cortex-M4 TRM r0p1, tables 3-1 and 7-1)
//! | class | cycles |
//! |---|---|
//! | data processing, MUL/MLA, SMUAD/SMLAD/SMLAxy, SMULL/SMLAL, VADD/VSUB/VMUL/VABS/VNEG/VCMP/VCVT/VMOV/VMRS | 1 |
//! | VMLA/VMLS/VNMLA/VFMA (F32) | 3 (the TRM's figure; back-to-back independent ones overlap on the real pipeline, so this is an upper estimate) |
//! | LDR/STR (any width), VLDR/VSTR | 2 |
//! | LDRD/STRD | 3 |
//! | LDM/STM/PUSH/POP, VLDM/VSTM/VPUSH/VPOP | 1 + N registers (+2 if POP loads pc) |
//! | SDIV/UDIV | 12 (worst case, 2..12) |
//! | VDIV/VSQRT | 14 |
//! | branch taken (B, BL, BX, CBZ/CBNZ; detected from the trace) | 1 + P, P = 2 (pipeline refill, 1..3) |
//! | branch not taken | 1 |
//! Zero-wait-state memory is assumed (SRAM; flash at 80 MHz with the ART
//! accelerator hitting). Cycles are converted to time at 80 MHz.
use anyhow::{Context, bail, ensure};
use brdf_meter::kernel;
use serde::Serialize;
use std::collections::HashMap;
use std::path::Path;

/// What the QEMU bench measured.
#[derive(Clone, Debug, Serialize)]
pub struct KernelCounts {
    /// n, m of the bench.
    pub n: usize,
    /// Readings.
    pub m: usize,
    /// f32 kernel (`mat_vec_f32_into`, m = 7 assembly), instructions per point.
    pub f32_instructions: f64,
    /// Its cycle estimate per point.
    pub f32_cycles: f64,
    /// Instructions per multiply-accumulate (n m MACs per point).
    pub f32_per_mac: f64,
    /// Q15 kernel alone (SMLAD), instructions per point.
    pub q15_instructions: f64,
    /// Its cycle estimate.
    pub q15_cycles: f64,
    /// Instructions per useful multiply-accumulate (n m).
    pub q15_per_mac: f64,
    /// Quantising one point's readings, instructions.
    pub quantise_v_instructions: f64,
    /// Its cycles.
    pub quantise_v_cycles: f64,
    /// Scaling the accumulators back to f32 (n bins), instructions.
    pub dequantise_instructions: f64,
    /// Its cycles.
    pub dequantise_cycles: f64,
    /// Adding the affine constant term (n bins), instructions.
    pub offset_instructions: f64,
    /// Its cycles.
    pub offset_cycles: f64,
    /// Selection rule: (K, instructions, cycles) for K = 1..16.
    pub select: Vec<(usize, f64, f64)>,
    /// Load-time quantisation of one W, instructions.
    pub quantise_w_instructions: f64,
    /// Bit-exact agreement of every device result with the host's.
    pub bit_exact: bool,
    /// What was compared.
    pub compared: String,
    /// The command that produced the trace.
    pub command: String,
}

struct Insn {
    len: u32,
    mnemonic: String,
    operands: String,
}

fn parse_objdump(text: &str) -> HashMap<u32, Insn> {
    let mut map = HashMap::new();
    for line in text.lines() {
        let mut parts = line.split('\t');
        let Some(addr) = parts.next() else { continue };
        let addr = addr.trim();
        let Some(addr) = addr.strip_suffix(':') else { continue };
        let Ok(a) = u32::from_str_radix(addr, 16) else { continue };
        let Some(hex) = parts.next() else { continue };
        let len: u32 = hex.split_whitespace().map(|h| h.len() as u32 / 2).sum();
        let mnemonic = parts.next().unwrap_or("").trim().to_string();
        let operands = parts.next().unwrap_or("").trim().to_string();
        if len > 0 && !mnemonic.is_empty() {
            map.insert(a, Insn { len, mnemonic, operands });
        }
    }
    map
}

fn reg_count(ops: &str) -> u32 {
    let Some(l) = ops.find('{') else { return 1 };
    let Some(r) = ops[l..].find('}') else { return 1 };
    let mut n = 0;
    for item in ops[l + 1..l + r].split(',') {
        let item = item.trim();
        let width = if item.starts_with('d') { 2 } else { 1 };
        if let Some((a, b)) = item.split_once('-') {
            let num =
                |s: &str| s.trim().trim_start_matches(|c: char| c.is_ascii_alphabetic()).parse::<u32>().unwrap_or(0);
            n += (num(b).saturating_sub(num(a)) + 1) * width;
        } else if !item.is_empty() {
            n += width;
        }
    }
    n.max(1)
}

/// Cycles of one executed instruction (see the module's table).
fn cycles(i: &Insn, taken: bool) -> f64 {
    let mn = i.mnemonic.trim_end_matches(".w").trim_end_matches(".n");
    let base = mn.split('.').next().unwrap_or(mn);
    let starts = |p: &str| base.starts_with(p);
    let is_branch = matches!(base, "b" | "bl" | "bx" | "blx" | "cbz" | "cbnz")
        || (base.len() == 3 && base.starts_with('b') && !matches!(base, "bic" | "bfi" | "bfc" | "bkpt"));
    if is_branch {
        return if taken { 3.0 } else { 1.0 };
    }
    if starts("vldm") || starts("vstm") || starts("vpush") || starts("vpop") {
        return 1.0 + reg_count(&i.operands) as f64;
    }
    if starts("ldm") || starts("stm") || base == "push" || base == "pop" {
        let pc = if i.operands.contains("pc") { 2.0 } else { 0.0 };
        return 1.0 + reg_count(&i.operands) as f64 + pc;
    }
    if starts("ldrd") || starts("strd") {
        return 3.0;
    }
    if starts("ldr") || starts("str") || starts("vldr") || starts("vstr") {
        return 2.0;
    }
    if starts("vmla") || starts("vmls") || starts("vnmla") || starts("vnmls") || starts("vfma") || starts("vfms") {
        return 3.0;
    }
    if starts("vdiv") || starts("vsqrt") {
        return 14.0;
    }
    if starts("sdiv") || starts("udiv") {
        return 12.0;
    }
    1.0
}

/// One segment between two marks.
#[derive(Clone, Debug)]
pub struct Segment {
    /// The words of its `SEG` line.
    pub name: Vec<String>,
    /// Instructions executed.
    pub instructions: f64,
    /// Their cycle estimate.
    pub cycles: f64,
}

fn words(line: &str, tag: &str) -> Option<Vec<u32>> {
    let rest = line.strip_prefix(tag)?;
    Some(rest.split_whitespace().filter_map(|h| u32::from_str_radix(h, 16).ok()).collect())
}

/// Runs a traced bench script (`scripts/trace-bench.sh` behind it) in
/// `root` with output folder `dir`, counts its segments between calls of
/// the benches' `bench_mark` (`src/bin/bench_io`), and deletes the trace
/// (hundreds of MB) once counted.
pub fn run_traced(root: &Path, script: &str, dir: &Path) -> anyhow::Result<Vec<Segment>> {
    let script = root.join(script);
    let status = std::process::Command::new("bash")
        .arg(&script)
        .arg(dir)
        .current_dir(root)
        .status()
        .with_context(|| format!("running {}", script.display()))?;
    anyhow::ensure!(status.success(), "{} failed ({status})", script.display());
    let segs = count_segments(dir, "bench_mark");
    let _ = std::fs::remove_file(dir.join("trace.txt"));
    segs
}

/// Cuts a bench's trace (`trace.txt`, with `nm.txt`, `objdump.txt` and
/// `stdout.txt` beside it, as the bench scripts write them) at every
/// execution of the function `mark_symbol`, and counts each segment's instructions
/// (the mark's own excluded) and cycles (the module's table), named by the
/// `SEG` lines the firmware printed, in order.
pub fn count_segments(dir: &Path, mark_symbol: &str) -> anyhow::Result<Vec<Segment>> {
    let read =
        |f: &str| std::fs::read_to_string(dir.join(f)).with_context(|| format!("reading {}", dir.join(f).display()));
    let nm = read("nm.txt")?;
    let (mark, mark_size) = nm
        .lines()
        .filter_map(|l| {
            let p: Vec<&str> = l.split_whitespace().collect();
            (p.len() == 4 && p[3] == mark_symbol)
                .then(|| (u32::from_str_radix(p[0], 16).ok(), u32::from_str_radix(p[1], 16).ok()))
        })
        .next()
        .and_then(|(a, s)| Some((a?, s?)))
        .with_context(|| format!("no {mark_symbol} symbol in nm.txt"))?;
    let insns = parse_objdump(&read("objdump.txt")?);
    let stdout = read("stdout.txt")?;
    let seg_names: Vec<Vec<String>> = stdout
        .lines()
        .filter_map(|l| l.strip_prefix("SEG "))
        .map(|s| s.split_whitespace().map(str::to_string).collect())
        .collect();
    let trace = std::fs::File::open(dir.join("trace.txt")).context("opening trace.txt")?;
    let mut segs: Vec<(f64, f64)> = Vec::new();
    let mut cur: Option<(f64, f64)> = None;
    use std::io::BufRead;
    // One pc behind: a taken branch is one whose next pc is not the fall-through.
    let mut pending: Option<u32> = None;
    let account = |cur: &mut Option<(f64, f64)>, pc: u32, next: Option<u32>| {
        if (mark..mark + mark_size).contains(&pc) {
            return;
        }
        if let Some(c) = cur.as_mut() {
            c.0 += 1.0;
            let cyc = match insns.get(&pc) {
                Some(i) => cycles(i, next.is_some_and(|nx| nx != pc + i.len)),
                None => 1.0,
            };
            c.1 += cyc;
        }
    };
    for line in std::io::BufReader::new(trace).lines() {
        let line = line?;
        let Some(field) = line.split('/').nth(1) else { continue };
        let Ok(pc) = u64::from_str_radix(field, 16) else { continue };
        let pc = pc as u32 & !1;
        if let Some(prev) = pending.take() {
            account(&mut cur, prev, Some(pc));
        }
        if pc == mark {
            if let Some(c) = cur.take() {
                segs.push(c);
            }
            cur = Some((0.0, 0.0));
            continue;
        }
        pending = Some(pc);
    }
    if let Some(prev) = pending.take() {
        account(&mut cur, prev, None);
    }
    ensure!(segs.len() == seg_names.len(), "trace has {} segments, the firmware named {}", segs.len(), seg_names.len());
    Ok(seg_names.into_iter().zip(segs).map(|(name, (i, c))| Segment { name, instructions: i, cycles: c }).collect())
}

/// Runs `scripts/kernel-bench.sh` in `root` and analyses its output.
pub fn run_bench(root: &Path) -> anyhow::Result<KernelCounts> {
    let out_dir = root.join("target/kernel-bench");
    let script = root.join("scripts/kernel-bench.sh");
    ensure!(script.exists(), "{} not found", script.display());
    let status = std::process::Command::new("bash")
        .arg(&script)
        .arg(&out_dir)
        .current_dir(root)
        .status()
        .with_context(|| format!("running {}", script.display()))?;
    ensure!(status.success(), "{} failed ({status})", script.display());
    analyse(&out_dir)
}

/// Analyses a kernel-bench output directory (see the module docs).
pub fn analyse(dir: &Path) -> anyhow::Result<KernelCounts> {
    let stdout = std::fs::read_to_string(dir.join("stdout.txt"))
        .with_context(|| format!("reading {}", dir.join("stdout.txt").display()))?;
    let segments = count_segments(dir, "kernel_bench_mark")?;
    let avg = |kind: &str, extra: Option<&str>| -> anyhow::Result<(f64, f64)> {
        let sel: Vec<&Segment> = segments
            .iter()
            .filter(|s| s.name[0] == kind && extra.is_none_or(|e| s.name.get(2).is_some_and(|x| x == e)))
            .collect();
        ensure!(!sel.is_empty(), "no {kind} segment");
        let k = sel.len() as f64;
        Ok((sel.iter().map(|s| s.instructions).sum::<f64>() / k, sel.iter().map(|s| s.cycles).sum::<f64>() / k))
    };
    let (n, m) = (81usize, 7usize);
    let (f32_i, f32_c) = avg("f32", None)?;
    let (q_i, q_c) = avg("q15", None)?;
    let (qv_i, qv_c) = avg("quantise_v", None)?;
    let (dq_i, dq_c) = avg("dequantise", None)?;
    let (qw_i, _) = avg("quantise_w", None)?;
    let (of_i, of_c) = avg("offset", None)?;
    let mut select = Vec::new();
    for kk in 1..=16usize {
        let (i, c) = avg("select", Some(&format!("{kk:08x}")))?;
        select.push((kk, i, c));
    }

    // Bit-exact check against the host.
    let w: Vec<f32> =
        stdout.lines().find_map(|l| words(l, "W ")).context("no W line")?.into_iter().map(f32::from_bits).collect();
    let cents: Vec<f32> =
        stdout.lines().find_map(|l| words(l, "C ")).context("no C line")?.into_iter().map(f32::from_bits).collect();
    ensure!(w.len() == n * m, "W has {} values", w.len());
    let mut packed = vec![0u32; kernel::q15_w_words(n, m)];
    let mut inv = vec![0.0f32; n];
    kernel::quantise_w_q15(&w, n, m, &mut packed, &mut inv);
    let vs: Vec<Vec<u32>> = stdout.lines().filter_map(|l| words(l, "V ")).collect();
    let outs: Vec<Vec<u32>> = stdout.lines().filter_map(|l| words(l, "OUT ")).collect();
    let accs: Vec<Vec<u32>> = stdout.lines().filter_map(|l| words(l, "ACC ")).collect();
    let rhoqs: Vec<Vec<u32>> = stdout.lines().filter_map(|l| words(l, "RHOQ ")).collect();
    let sels: Vec<Vec<u32>> = stdout.lines().filter_map(|l| words(l, "SEL ")).collect();
    let ofs: Vec<Vec<u32>> = stdout.lines().filter_map(|l| words(l, "OFS ")).collect();
    ensure!(ofs.len() == vs.len(), "incomplete offset results");
    ensure!(
        !vs.is_empty()
            && vs.len() == outs.len()
            && vs.len() == accs.len()
            && vs.len() == rhoqs.len()
            && vs.len() == sels.len(),
        "incomplete results"
    );
    let mut compared = 0usize;
    for p in 0..vs.len() {
        let v: Vec<f32> = vs[p].iter().map(|b| f32::from_bits(*b)).collect();
        let mut o = vec![0.0f32; n];
        kernel::mat_vec_f32_slice(&w, &v, &mut o);
        let host_out: Vec<u32> = o.iter().map(|x| x.to_bits()).collect();
        if host_out != outs[p] {
            bail!("point {p}: the device's f32 results differ from the host's");
        }
        let mut vq = vec![0u32; kernel::q15_v_words(m)];
        let k = kernel::quantise_v_q15(&v, &mut vq);
        let mut acc = vec![0i32; kernel::q15_acc_len(n)];
        kernel::mat_vec_q15_portable(&packed, &vq, m, &mut acc);
        let mut host_acc = vec![k as u32];
        host_acc.extend(acc.iter().map(|a| *a as u32));
        if host_acc != accs[p] {
            bail!("point {p}: the device's Q15 accumulators differ from the host's");
        }
        let mut rq = vec![0.0f32; n];
        kernel::dequantise_q15(&acc[..n], &inv, k, &mut rq);
        if rq.iter().map(|x| x.to_bits()).collect::<Vec<_>>() != rhoqs[p] {
            bail!("point {p}: the device's Q15 estimates differ from the host's");
        }
        let sum: Vec<u32> = o.iter().enumerate().map(|(j, a)| (v[j % m] + a).to_bits()).collect();
        if sum != ofs[p] {
            bail!("point {p}: the device's offset additions differ from the host's");
        }
        for kk in 1..=16usize {
            let s = kernel::select_cluster(&cents[..kk * m], &v) as u32;
            if s != sels[p][kk - 1] {
                bail!("point {p}, K = {kk}: the device selected cluster {} and the host {s}", sels[p][kk - 1]);
            }
        }
        compared += 3 * n + 1 + 16 + n;
    }
    let macs = (n * m) as f64;
    Ok(KernelCounts {
        n,
        m,
        f32_instructions: f32_i,
        f32_cycles: f32_c,
        f32_per_mac: f32_i / macs,
        q15_instructions: q_i,
        q15_cycles: q_c,
        q15_per_mac: q_i / macs,
        quantise_v_instructions: qv_i,
        quantise_v_cycles: qv_c,
        dequantise_instructions: dq_i,
        dequantise_cycles: dq_c,
        offset_instructions: of_i,
        offset_cycles: of_c,
        select,
        quantise_w_instructions: qw_i,
        bit_exact: true,
        compared: format!(
            "{} points: f32 results, Q15 block exponents and accumulators, Q15 estimates, offset sums, 16 selections each ({compared} values), bit for bit",
            vs.len()
        ),
        command: "scripts/kernel-bench.sh target/kernel-bench".into(),
    })
}

/// Attaches device costs to the rows whose kernels the bench measured
/// (n = 81, m = 7 only).
pub fn attach(rows: &mut [super::Row], kc: &KernelCounts) {
    let nm = kc.n * kc.m;
    let mk = |i: f64, c: f64, what: String| super::DeviceCost {
        instructions: i,
        cycles: c,
        seconds_at_80mhz: c / 80e6,
        counted: what,
    };
    for r in rows.iter_mut() {
        let sel = |id: &str| -> Option<(usize, f64, f64)> {
            let rest = id.strip_prefix("clustered-affine-k").or_else(|| id.strip_prefix("clustered-k"))?;
            let k: usize = rest.split('-').next()?.parse().ok()?;
            kc.select.iter().find(|s| s.0 == k).copied()
        };
        let affine = r.id.starts_with("clustered-affine");
        r.device = match r.group.as_str() {
            "linear" | "prior" if r.macs_per_point == Some(nm) => {
                Some(mk(kc.f32_instructions, kc.f32_cycles, "f32 kernel".into()))
            }
            "clustered" if affine => sel(&r.id).map(|(k, i, c)| {
                mk(
                    kc.f32_instructions + i + kc.offset_instructions,
                    kc.f32_cycles + c + kc.offset_cycles,
                    format!("select K={k} + f32 kernel + {} adds", kc.n),
                )
            }),
            "clustered" => sel(&r.id)
                .map(|(k, i, c)| mk(kc.f32_instructions + i, kc.f32_cycles + c, format!("select K={k} + f32 kernel"))),
            "format" => {
                let (si, sc, what) = match sel(&r.id) {
                    Some((k, i, c)) => (i, c, format!("select K={k} + ")),
                    None => (0.0, 0.0, String::new()),
                };
                let (oi, oc, ow) =
                    if affine { (kc.offset_instructions, kc.offset_cycles, " + offset") } else { (0.0, 0.0, "") };
                Some(mk(
                    si + kc.quantise_v_instructions + kc.q15_instructions + kc.dequantise_instructions + oi,
                    sc + kc.quantise_v_cycles + kc.q15_cycles + kc.dequantise_cycles + oc,
                    format!("{what}quantise v + Q15 kernel + scale to f32{ow}"),
                ))
            }
            _ => None,
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn register_lists_and_cycle_classes() {
        let i = |mn: &str, ops: &str| Insn { len: 4, mnemonic: mn.into(), operands: ops.into() };
        assert_eq!(reg_count("r0!, {r4, r5, r6, r7, r8, r9, sl}"), 7);
        assert_eq!(reg_count("r0!, {s16-s29}"), 14);
        assert_eq!(reg_count("{d8-d14}"), 14);
        assert_eq!(cycles(&i("vldmia", "r0!, {s16-s29}"), false), 15.0);
        assert_eq!(cycles(&i("vmla.f32", "s8, s16, s0"), false), 3.0);
        assert_eq!(cycles(&i("smlad", "r4, r5, ip, r4"), false), 1.0);
        assert_eq!(cycles(&i("strd", "r4, r7, [r1], #8"), false), 3.0);
        assert_eq!(cycles(&i("ldr.w", "ip, [r3, #4]"), false), 2.0);
        assert_eq!(cycles(&i("bne.n", "80025f2"), true), 3.0);
        assert_eq!(cycles(&i("bne.n", "80025f2"), false), 1.0);
        assert_eq!(cycles(&i("bic.w", "r0, r0, #1"), false), 1.0);
        assert_eq!(cycles(&i("pop", "{r4, r5, r7, pc}"), true), 7.0);
    }

    #[test]
    fn objdump_lines_parse() {
        let m = parse_objdump(" 8001e62:\tb580      \tpush\t{r7, lr}\n 8002654:\tecb0 8a0e \tvldmia\tr0!, {s16-s29}\n");
        assert_eq!(m[&0x8001e62].len, 2);
        assert_eq!(m[&0x8002654].len, 4);
        assert_eq!(m[&0x8002654].mnemonic, "vldmia");
    }
}
