//! The firmware's flash and RAM budget, checked against the build.
//!
//! The numbers that must agree come from their single sources: the memory
//! map from `memory.x` (the linker script the firmware is linked with), the
//! image and static RAM sizes from the firmware ELF's section headers, the
//! blob size from `brdf_meter::blob::Dims::blob_len` and the slot header from
//! `brdf_meter::store::SLOT_HEADER_LEN`.
//!
//! The calibration for the largest configuration (`shape::board::MAX_ZONES`
//! zones of n x m matrices, P = 128 pixels: about 320 KiB) cannot live in the
//! 96 KiB of RAM;
//! the firmware reads its matrices in place from the memory-mapped slot
//! (`BlobView::matrix_in_place`), which needs the blob 4-byte aligned in
//! flash. So the budget is:
//! - image (vector table, code, read-only data, .data's initial values) <=
//!   its own region: an application's the active image region (FLASH), the
//!   bootloader's BOOTLOADER (24 KiB); the map's regions follow each other
//!   without overlap inside the chip, in whole erase pages;
//! - slot header + blob + signature trailer <= one calibration slot;
//! - static RAM (.data, .bss, .uninit; the executor's task futures and every
//!   buffer are statics) <= RAM, the part of SRAM1 after the stack;
//! - the stack reserve <= STACK, the start of SRAM1, which the image's
//!   stack symbols must be (a stack that outgrows it then faults off the
//!   start of SRAM1 rather than overwriting the statics: memory.x says why).
use std::fmt::Write as _;

use anyhow::{Context, Result, anyhow, bail};
use brdf_meter::blob::Dims;
use brdf_meter::shape;
use brdf_meter::store::SLOT_HEADER_LEN;

use crate::device::memory_map::{MemoryMap, Region};

/// Total flash of the STM32L475VG.
pub const CHIP_FLASH: Region = Region { origin: shape::FLASH_BASE, length: shape::FLASH_SIZE };

/// The largest calibration the product must run: `shape::board::MAX_ZONES`
/// zones of n x m matrices for a 128-pixel sensor (the one constant the
/// estimation side sizes its calibrations by).
pub const MAX_DIMS: Dims =
    Dims { n: shape::BINS, m: shape::LEDS, zones: shape::board::MAX_ZONES, pixels: shape::board::PIXELS };

/// Stack the firmware needs beyond its statics: interrupt handlers and the
/// executor's poll frames (task state itself is static). The QEMU tests
/// measure the application's high-water mark (the stack is painted at reset,
/// [`crate::device::stack_use`]): 5.6 KB at most, over provisioning,
/// measuring, inspecting and updates, and they fail above this reserve. The
/// board's own frames are larger where they hold a line's pixels (P = 128
/// against QEMU's 32) and it serves USB, so its reserve keeps about half
/// again that. memory.x's STACK region must hold it.
pub const STACK_RESERVE: u64 = 12 * 1024;

/// One allocated section of an ELF image.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Section {
    /// Name.
    pub name: String,
    /// Run-time address.
    pub addr: u32,
    /// Size in bytes.
    pub size: u32,
    /// Whether the file holds its bytes (false for .bss-like sections).
    pub has_bytes: bool,
}

/// The allocated (loaded or zero-initialised) sections of a 32-bit
/// little-endian ELF file.
pub fn elf_sections(elf: &[u8]) -> Result<Vec<Section>> {
    use object::read::elf::{ElfFile32, SectionHeader as _};
    use object::{Object as _, ObjectSection as _};
    let file = ElfFile32::<object::LittleEndian>::parse(elf)
        .map_err(|e| anyhow!("not a 32-bit little-endian ELF (a Cortex-M image): {e}"))?;
    let endian = file.endian();
    let mut out = Vec::new();
    for s in file.sections() {
        let h = s.elf_section_header();
        if (h.sh_flags(endian) & object::elf::SHF_ALLOC).0 == 0 || h.sh_size(endian) == 0 {
            continue;
        }
        let name = s.name().map_err(|e| anyhow!("malformed ELF section name: {e}"))?;
        out.push(Section {
            name: name.to_string(),
            addr: h.sh_addr(endian),
            size: h.sh_size(endian),
            has_bytes: h.sh_type(endian) != object::elf::SHT_NOBITS,
        });
    }
    Ok(out)
}

/// Use of one resource against its limit.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Line {
    /// What is measured.
    pub what: String,
    /// Bytes used.
    pub used: u64,
    /// Bytes available.
    pub limit: u64,
}

impl Line {
    /// Whether it fits.
    pub fn ok(&self) -> bool {
        self.used <= self.limit
    }
}

/// The budget of one firmware image.
#[derive(Clone, Debug)]
pub struct Budget {
    /// Firmware name.
    pub name: String,
    /// The calibration its slots were checked for (`None`: an image with
    /// no slots, a bench, whose budget is its stack alone).
    pub calibration: Option<Dims>,
    /// The lines; all must fit.
    pub lines: Vec<Line>,
    /// Layout problems (overlaps, misalignment), each a failure.
    pub problems: Vec<String>,
    /// Facts printed with the table.
    pub notes: Vec<String>,
}

impl Budget {
    /// Whether every line fits and the layout is sound.
    pub fn ok(&self) -> bool {
        self.problems.is_empty() && self.lines.iter().all(Line::ok)
    }

    /// A plain-text table.
    pub fn table(&self) -> String {
        let mut s = String::new();
        match self.calibration {
            Some(d) => {
                let _ = writeln!(
                    s,
                    "budget of {} (calibration Z = {}, n = {}, m = {}, P = {}):",
                    self.name, d.zones, d.n, d.m, d.pixels
                );
            }
            None => {
                let _ = writeln!(s, "budget of {}:", self.name);
            }
        }
        let _ = writeln!(s, "  {:<44} {:>10} {:>10} {:>10} {:>6}", "resource", "used", "limit", "free", "use%");
        for l in &self.lines {
            let free = l.limit as i64 - l.used as i64;
            let pct = if l.limit == 0 { 100.0 } else { 100.0 * l.used as f64 / l.limit as f64 };
            let verdict = if l.ok() { "ok" } else { "OVER BUDGET" };
            let _ =
                writeln!(s, "  {:<44} {:>10} {:>10} {:>10} {:>5.1}%  {}", l.what, l.used, l.limit, free, pct, verdict);
        }
        for n in &self.notes {
            let _ = writeln!(s, "  note: {n}");
        }
        for p in &self.problems {
            let _ = writeln!(s, "  LAYOUT PROBLEM: {p}");
        }
        s
    }
}

fn inside(r: &Region, addr: u32) -> bool {
    (r.origin as u64..r.end()).contains(&(addr as u64))
}

/// Which region of the map an image links into.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageKind {
    /// An application (board-fw, qemu-fw): the active image region, ACTIVE.
    Application,
    /// The bootloader: BOOTLOADER, at the reset vector.
    Bootloader,
}

impl ImageKind {
    /// The region and its memory.x name.
    pub fn region(self, map: &MemoryMap) -> (&'static str, Region) {
        match self {
            Self::Application => ("ACTIVE", map.flash),
            Self::Bootloader => ("BOOTLOADER", map.bootloader),
        }
    }
}

/// The map's own soundness: regions inside the chip, in address order
/// without overlap, whole erase pages; blobs 4-byte aligned in their slots.
fn layout_problems(map: &MemoryMap) -> Vec<String> {
    let mut problems = Vec::new();
    let regions = map.flash_regions();
    for (n, r) in regions {
        if r.origin < CHIP_FLASH.origin || r.end() > CHIP_FLASH.end() {
            problems.push(format!("{n} is outside the chip's flash"));
        }
        if r.origin % shape::FLASH_PAGE as u32 != 0 || r.length % shape::FLASH_PAGE as u32 != 0 {
            problems.push(format!("{n} is not whole 2 KiB erase pages"));
        }
    }
    for w in regions.windows(2) {
        let ((a, ra), (b, rb)) = (w[0], w[1]);
        if ra.end() > rb.origin as u64 {
            problems.push(format!("{a} ends at {:#x}, past {b} at {:#x}", ra.end(), rb.origin));
        }
    }
    if map.stack.end() != map.ram.origin as u64 {
        problems.push(format!(
            "STACK ends at {:#x}, not where RAM (the statics) begins at {:#x}: a stack below the statics is what \
             makes its overflow fault instead of overwriting them",
            map.stack.end(),
            map.ram.origin
        ));
    }
    if (map.dfu.length as u64) < map.flash.length as u64 + shape::FLASH_PAGE as u64 {
        problems.push("DFU is not one page larger than the active image (embassy-boot's swap needs it)".into());
    }
    for (n, r) in [("CAL_SLOT_A", map.slot_a), ("CAL_SLOT_B", map.slot_b)] {
        if !(r.origin as usize + SLOT_HEADER_LEN).is_multiple_of(4) {
            problems.push(format!("the blob in {n} would not be 4-byte aligned: matrices cannot be read in place"));
        }
    }
    problems
}

/// Checks one firmware image's sections against the memory map.
pub fn check(
    name: &str,
    kind: ImageKind,
    sections: &[Section],
    map: &MemoryMap,
    dims: Dims,
    stack_reserve: u64,
) -> Budget {
    let mut problems = layout_problems(map);
    let (region_name, region) = kind.region(map);
    let mut image = 0u64;
    let mut statics = 0u64;
    for s in sections {
        let in_image = inside(&region, s.addr);
        let in_ram = inside(&map.ram, s.addr);
        if let Some((other, _)) = map.flash_regions().into_iter().find(|(n, r)| *n != region_name && inside(r, s.addr))
        {
            problems.push(format!(
                "section {} at {:#x} lies in {other}, outside the image's {region_name}",
                s.name, s.addr
            ));
        }
        if in_ram {
            statics += s.size as u64;
        }
        // Loaded bytes live in flash: code and constants at their address,
        // .data's initial values right after them.
        if s.has_bytes && (in_image || in_ram) {
            image += s.size as u64;
        }
        if !in_image && !in_ram {
            problems.push(format!("section {} at {:#x} is in neither {region_name} nor RAM", s.name, s.addr));
        }
    }
    let blob = dims.blob_len() as u64;
    let lines = vec![
        Line { what: format!("flash: image in {region_name}"), used: image, limit: region.length as u64 },
        Line {
            what: format!("flash: slot header + blob ({} B) + signature per slot", blob),
            used: SLOT_HEADER_LEN as u64 + blob + brdf_meter::signed::TRAILER_LEN as u64,
            limit: map.slot_a.length.min(map.slot_b.length) as u64,
        },
        Line { what: "RAM: statics (after the stack)".into(), used: statics, limit: map.ram.length as u64 },
        Line { what: "STACK: the reserve the stack needs".into(), used: stack_reserve, limit: map.stack.length as u64 },
    ];
    let matrices = 4 * (dims.zones * dims.n * dims.m) as u64;
    let notes = vec![format!(
        "the {} B of matrices stay in flash and are read in place; the RAM left after the statics is {} B",
        matrices,
        (map.ram.length as u64).saturating_sub(statics)
    )];
    Budget { name: name.into(), calibration: Some(dims), lines, problems, notes }
}

/// Reads an ELF file and checks it against `memory.x`.
pub fn check_file(path: &std::path::Path, kind: ImageKind, script: &str) -> Result<Budget> {
    let elf = std::fs::read(path).with_context(|| format!("cannot read firmware {}", path.display()))?;
    let sections = elf_sections(&elf).with_context(|| format!("{}", path.display()))?;
    if sections.is_empty() {
        bail!("{}: no allocated sections", path.display());
    }
    let map = MemoryMap::from_script(script)?;
    let name = path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
    let mut budget = check(&name, kind, &sections, &map, MAX_DIMS, STACK_RESERVE);
    add_stack_checks(&mut budget, &elf, path, &map, STACK_RESERVE / 2)?;
    Ok(budget)
}

/// Reads a QEMU bench's ELF file (kernel-bench, line-bench, inspect-bench,
/// verify-bench) and checks its stack against `memory.x`: its stack is
/// memory.x's STACK, and no function's frame is larger than the stack
/// reserve. The benches run the board's kernels from one `main`, which
/// holds their inputs; nothing runs them in the test suite (their traces
/// take minutes), so a frame too large for the stack is seen here or, run
/// by hand, as a lockup (one `main` once took 22,784 B of the 16 KiB).
/// A bench's flash and statics are the linker's to refuse: it has no
/// calibration slots to leave room for.
pub fn check_bench_file(path: &std::path::Path, script: &str) -> Result<Budget> {
    let elf = std::fs::read(path).with_context(|| format!("cannot read bench firmware {}", path.display()))?;
    let map = MemoryMap::from_script(script)?;
    let name = path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
    let mut budget = Budget { name, calibration: None, lines: Vec::new(), problems: Vec::new(), notes: Vec::new() };
    add_stack_checks(&mut budget, &elf, path, &map, STACK_RESERVE)?;
    Ok(budget)
}

/// Adds an image's stack checks to its budget: its stack symbols are
/// memory.x's STACK, and its largest function frame is at most
/// `frame_limit` (with the four largest named in the notes).
fn add_stack_checks(
    budget: &mut Budget,
    elf: &[u8],
    path: &std::path::Path,
    map: &MemoryMap,
    frame_limit: u64,
) -> Result<()> {
    let stack = crate::device::stack_use::StackRegion::of_elf(elf, &budget.name)?;
    if (stack.bottom, u64::from(stack.top)) != (map.stack.origin, map.stack.end()) {
        budget.problems.push(format!(
            "the image's stack runs {:#x}..{:#x}, not memory.x's STACK {:#x}..{:#x} (was it linked with this memory.x?)",
            stack.bottom,
            stack.top,
            map.stack.origin,
            map.stack.end()
        ));
    }
    let frames = crate::device::stack_frames::frames(elf).with_context(|| format!("{}", path.display()))?;
    budget.lines.push(largest_frame_line(&frames, frame_limit));
    budget.notes.push(format!(
        "largest stack frames: {}",
        frames.iter().take(4).map(|f| format!("{} B {}", f.bytes, f.function)).collect::<Vec<_>>().join("; ")
    ));
    Ok(())
}

/// One function's frame against `limit`: for an application half the
/// stack reserve, as a frame larger than that leaves too little of the
/// reserve for the calls under it (the board's stack is only measured in
/// QEMU, `crate::device::stack_use`).
fn largest_frame_line(frames: &[crate::device::stack_frames::Frame], limit: u64) -> Line {
    Line { what: "stack: largest function frame".into(), used: frames.first().map_or(0, |f| u64::from(f.bytes)), limit }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device::memory_map::MEMORY_X;

    fn sec(name: &str, addr: u32, size: u32, has_bytes: bool) -> Section {
        Section { name: name.into(), addr, size, has_bytes }
    }

    fn board_map() -> MemoryMap {
        MemoryMap::board()
    }

    fn typical() -> Vec<Section> {
        vec![
            sec(".vector_table", 0x0800_7000, 0x188, true),
            sec(".text", 0x0800_7188, 60_000, true),
            sec(".rodata", 0x0801_7000, 8_000, true),
            sec(".data", 0x2000_4000, 100, true),
            sec(".bss", 0x2000_4064, 30_000, false),
            sec(".uninit", 0x2000_C000, 1_024, false),
        ]
    }

    #[test]
    fn a_typical_image_fits_and_the_numbers_add_up() {
        let b = check("fw", ImageKind::Application, &typical(), &board_map(), MAX_DIMS, STACK_RESERVE);
        assert!(b.ok(), "{}", b.table());
        assert_eq!(b.lines[0].used, 0x188 + 60_000 + 8_000 + 100);
        assert_eq!(b.lines[1].used, (SLOT_HEADER_LEN + MAX_DIMS.blob_len() + brdf_meter::signed::TRAILER_LEN) as u64);
        assert_eq!(b.lines[2].used, 100 + 30_000 + 1_024);
        assert_eq!((b.lines[3].used, b.lines[3].limit), (STACK_RESERVE, 16 * 1024));
    }

    #[test]
    fn max_zones_is_the_largest_calibration_a_slot_holds() {
        let signed = |zones| SLOT_HEADER_LEN + Dims { zones, ..MAX_DIMS }.blob_len() + brdf_meter::signed::TRAILER_LEN;
        let slot = board_map().slot_a.length as usize;
        assert!(signed(MAX_DIMS.zones) <= slot, "MAX_ZONES does not fit a calibration slot");
        assert!(signed(MAX_DIMS.zones + 1) > slot, "one zone more would still fit: raise MAX_ZONES");
        // Z = 124 zones (Dims::blob_len): 1,928 B short of a slot with header and trailer.
        assert_eq!(MAX_DIMS.blob_len(), 325_640);
        // and its matrices could never be copied to RAM:
        let d = MAX_DIMS;
        assert!(4 * d.zones * d.n * d.m > board_map().ram.length as usize);
    }

    #[test]
    fn a_bootloader_is_checked_against_its_own_region() {
        let boot = vec![sec(".vector_table", 0x0800_0000, 0x188, true), sec(".text", 0x0800_0188, 20_000, true)];
        let b = check("boot", ImageKind::Bootloader, &boot, &board_map(), MAX_DIMS, STACK_RESERVE);
        assert!(b.ok(), "{}", b.table());
        assert_eq!(b.lines[0].limit, 24 * 1024);
        let mut big = boot.clone();
        big[1].size = 25_000;
        assert!(!check("boot", ImageKind::Bootloader, &big, &board_map(), MAX_DIMS, STACK_RESERVE).ok());
        // An application linked at the reset vector lies in the bootloader's region.
        let b = check("fw", ImageKind::Application, &boot, &board_map(), MAX_DIMS, STACK_RESERVE);
        assert!(b.problems.iter().any(|p| p.contains("lies in BOOTLOADER")), "{:?}", b.problems);
    }

    #[test]
    fn an_image_past_the_flash_region_fails() {
        let mut s = typical();
        s[1].size = 160 * 1024;
        let b = check("fw", ImageKind::Application, &s, &board_map(), MAX_DIMS, STACK_RESERVE);
        assert!(!b.ok());
        assert!(!b.lines[0].ok());
        assert!(b.table().contains("OVER BUDGET"));
    }

    #[test]
    fn statics_past_their_region_or_a_reserve_past_the_stack_fail() {
        let mut s = typical();
        s[4].size = 80 * 1024;
        let b = check("fw", ImageKind::Application, &s, &board_map(), MAX_DIMS, STACK_RESERVE);
        assert!(!b.lines[2].ok() && !b.ok());
        let b = check("fw", ImageKind::Application, &typical(), &board_map(), MAX_DIMS, 17 * 1024);
        assert!(!b.lines[3].ok() && !b.ok());
    }

    #[test]
    fn a_stack_above_the_statics_fails() {
        // cortex-m-rt's own layout: the statics at the start of SRAM1, the
        // stack over them, where an overflow writes over them unseen.
        let script = MEMORY_X
            .replace("STACK         : ORIGIN = 0x20000000", "STACK         : ORIGIN = 0x20014000")
            .replace("RAM           : ORIGIN = 0x20004000", "RAM           : ORIGIN = 0x20000000");
        assert_ne!(script, MEMORY_X, "the test must change memory.x");
        let map = MemoryMap::from_script(&script).unwrap();
        let b = check("fw", ImageKind::Application, &[], &map, MAX_DIMS, STACK_RESERVE);
        assert!(b.problems.iter().any(|p| p.contains("STACK ends at 0x20018000")), "{:?}", b.problems);
    }

    #[test]
    fn a_blob_larger_than_a_slot_fails() {
        let dims = Dims { n: 200, m: 7, zones: 128, pixels: 128 };
        let b = check("fw", ImageKind::Application, &typical(), &board_map(), dims, STACK_RESERVE);
        assert!(!b.lines[1].ok() && !b.ok());
    }

    #[test]
    fn a_memory_map_where_the_image_could_reach_the_next_region_fails() {
        let script = MEMORY_X.replace(
            "ACTIVE        : ORIGIN = 0x08007000, LENGTH = 160K",
            "ACTIVE        : ORIGIN = 0x08007000, LENGTH = 170K",
        );
        assert_ne!(script, MEMORY_X, "the test must change memory.x");
        let map = MemoryMap::from_script(&script).unwrap();
        let b = check("fw", ImageKind::Application, &typical(), &map, MAX_DIMS, STACK_RESERVE);
        assert!(!b.ok());
        assert!(b.problems.iter().any(|p| p.contains("past DFU")), "{:?}", b.problems);
        let mut s = typical();
        s.push(sec(".cal", 0x0806_0000, 4, true));
        let b = check("fw", ImageKind::Application, &s, &board_map(), MAX_DIMS, STACK_RESERVE);
        assert!(b.problems.iter().any(|p| p.contains("lies in CAL_SLOT_A")), "{:?}", b.problems);
    }

    /// A minimal ELF32 LE with sections: null, .text (PROGBITS, alloc),
    /// .bss (NOBITS, alloc), .comment (not alloc), .shstrtab.
    fn tiny_elf() -> Vec<u8> {
        let strtab = b"\0.text\0.bss\0.comment\0.shstrtab\0".to_vec();
        let mut elf = vec![0u8; 52];
        elf[0..4].copy_from_slice(b"\x7fELF");
        elf[4] = 1; // 32-bit
        elf[5] = 1; // little-endian
        elf[6] = 1; // ELF version 1 (current)
        let str_off = elf.len() as u32;
        elf.extend_from_slice(&strtab);
        while !elf.len().is_multiple_of(4) {
            elf.push(0);
        }
        let shoff = elf.len() as u32;
        let mut sh = |name: u32, kind: u32, flags: u32, addr: u32, off: u32, size: u32| {
            for v in [name, kind, flags, addr, off, size, 0, 0, 4, 0] {
                elf.extend_from_slice(&v.to_le_bytes());
            }
        };
        sh(0, 0, 0, 0, 0, 0);
        sh(1, 1, 2 | 4, 0x0800_0000, 0, 1234); // .text
        sh(7, 8, 2 | 1, 0x2000_4000, 0, 4321); // .bss
        sh(12, 1, 0, 0, 0, 99); // .comment
        sh(21, 3, 0, 0, str_off, strtab.len() as u32); // .shstrtab
        elf[0x20..0x24].copy_from_slice(&shoff.to_le_bytes());
        elf[0x2E..0x30].copy_from_slice(&40u16.to_le_bytes());
        elf[0x30..0x32].copy_from_slice(&5u16.to_le_bytes());
        elf[0x32..0x34].copy_from_slice(&4u16.to_le_bytes());
        elf
    }

    #[test]
    fn elf_sections_reads_allocated_sections_only() {
        let s = elf_sections(&tiny_elf()).unwrap();
        assert_eq!(s, vec![sec(".text", 0x0800_0000, 1234, true), sec(".bss", 0x2000_4000, 4321, false)]);
        assert!(elf_sections(b"not an elf at all, certainly not one for a Cortex-M4F target").is_err());
        let mut truncated = tiny_elf();
        truncated.truncate(80);
        assert!(elf_sections(&truncated).is_err());
    }
}
