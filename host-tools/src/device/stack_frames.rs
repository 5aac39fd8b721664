//! Each function's stack frame in a Cortex-M firmware image, read from its
//! prologue: the board's stack cannot be measured without a board
//! (`crate::device::stack_use` measures QEMU's), but one oversized frame
//! can be seen in the image itself, and one is enough to overflow it.
//!
//! A Thumb-2 prologue saves registers (`push`, `push.w`, `vpush`) and then
//! makes room for the locals (`sub sp, #imm`, `sub.w`/`subw sp, sp, #imm`,
//! or for a size no immediate encodes, `movw rN, #lo` (`movt rN, #hi`)
//! then `sub sp, rN`). [`frames`] decodes the first instructions of every
//! function symbol and adds those up. What it does not see: `alloca`-like
//! frames (Rust has none), and stack taken later in a function than its
//! first [`PROLOGUE_BYTES`] (LLVM allocates the whole frame in the
//! prologue).
use anyhow::anyhow;

/// How far into a function its prologue is looked for.
pub const PROLOGUE_BYTES: usize = 64;

/// One function's frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Frame {
    /// The function (demangled, without its hash).
    pub function: String,
    /// Bytes its prologue takes: saved registers and locals.
    pub bytes: u32,
}

/// The frames of every function in the ELF image `elf` with a prologue that
/// takes stack, largest first.
pub fn frames(elf: &[u8]) -> anyhow::Result<Vec<Frame>> {
    use object::{Object as _, ObjectSection as _, ObjectSymbol as _, SymbolKind};
    let file = object::File::parse(elf).map_err(|e| anyhow!("not an ELF file: {e}"))?;
    let mut out = Vec::new();
    for sym in file.symbols().filter(|s| s.kind() == SymbolKind::Text && s.size() > 0) {
        let Some(section) = sym.section_index().and_then(|i| file.section_by_index(i).ok()) else { continue };
        let data = section.data().map_err(|e| anyhow!("reading the section of {:?}: {e}", sym.name()))?;
        // Thumb symbols have bit 0 set.
        let at = ((sym.address() & !1) - section.address()) as usize;
        let len = (sym.size() as usize).min(PROLOGUE_BYTES);
        let Some(code) = data.get(at..at + len) else { continue };
        let bytes = prologue_bytes(code);
        if bytes > 0 {
            let name = sym.name().unwrap_or("?");
            out.push(Frame { function: format!("{:#}", rustc_demangle::demangle(name)), bytes });
        }
    }
    out.sort_by(|a, b| b.bytes.cmp(&a.bytes).then_with(|| a.function.cmp(&b.function)));
    Ok(out)
}

/// The stack the Thumb-2 prologue `code` takes (little-endian halfwords).
pub fn prologue_bytes(code: &[u8]) -> u32 {
    let hw = |k: usize| code.get(k..k + 2).map(|b| u16::from_le_bytes([b[0], b[1]]));
    // Registers loaded with a constant (movw / movt), for `sub sp, rN`.
    let mut consts = [0u32; 16];
    let mut total = 0u32;
    let mut k = 0;
    while let Some(h1) = hw(k) {
        if !matches!(h1 >> 11, 0b11101..=0b11111) {
            // 16-bit.
            if h1 & 0xFE00 == 0xB400 {
                // PUSH T1: r0-r7 (bits 0-7) and LR (bit 8).
                total += 4 * (h1 & 0x1FF).count_ones();
            } else if h1 & 0xFF80 == 0xB080 {
                // SUB (SP minus immediate) T1: imm7 words.
                total += u32::from(h1 & 0x7F) << 2;
            }
            k += 2;
            continue;
        }
        let Some(h2) = hw(k + 2) else { break };
        let rd = (h2 >> 8) & 0xF;
        let imm12 = (u32::from(h1 >> 10) & 1) << 11 | (u32::from(h2 >> 12) & 7) << 8 | u32::from(h2 & 0xFF);
        if h1 == 0xE92D {
            // PUSH T2 (STMDB SP!): register list.
            total += 4 * u32::from(h2 & 0x5FFF).count_ones();
        } else if h1 & 0xFFBF == 0xED2D && h2 & 0x0E00 == 0x0A00 {
            // VPUSH: imm8 words (double or single registers alike).
            total += 4 * u32::from(h2 & 0xFF);
        } else if h1 & 0xFBEF == 0xF1AD && h2 & 0x8F00 == 0x0D00 {
            // SUB (SP minus immediate) T2: sub.w sp, sp, #const.
            total += thumb_expand_imm(imm12);
        } else if h1 & 0xFBFF == 0xF2AD && h2 & 0x8F00 == 0x0D00 {
            // SUB (SP minus immediate) T3: subw sp, sp, #imm12.
            total += imm12;
        } else if h1 & 0xFBF0 == 0xF240 && h2 & 0x8000 == 0 {
            // MOVW T3: rd = imm16.
            consts[rd as usize] = u32::from(h1 & 0xF) << 12 | imm12;
        } else if h1 & 0xFBF0 == 0xF2C0 && h2 & 0x8000 == 0 {
            // MOVT: rd's top half.
            let hi = u32::from(h1 & 0xF) << 12 | imm12;
            consts[rd as usize] = (consts[rd as usize] & 0xFFFF) | hi << 16;
        } else if h1 & 0xFFEF == 0xEBAD && h2 & 0xFF00 == 0x0D00 && h2 & 0x00F0 == 0 {
            // SUB (SP minus register) T1, unshifted: sub.w sp, sp, rM.
            total += consts[usize::from(h2 & 0xF)];
        }
        k += 4;
    }
    total
}

/// ThumbExpandImm (ARMv7-M ARM A5.3.2) of a 12-bit modified immediate.
fn thumb_expand_imm(imm12: u32) -> u32 {
    let imm8 = imm12 & 0xFF;
    if imm12 >> 10 == 0 {
        match (imm12 >> 8) & 3 {
            0 => imm8,
            1 => imm8 << 16 | imm8,
            2 => imm8 << 24 | imm8 << 8,
            _ => imm8 << 24 | imm8 << 16 | imm8 << 8 | imm8,
        }
    } else {
        (0x80 | (imm12 & 0x7F)).rotate_right(imm12 >> 7)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn code(halfwords: &[u16]) -> Vec<u8> {
        halfwords.iter().flat_map(|h| h.to_le_bytes()).collect()
    }

    #[test]
    fn prologues_add_saved_registers_and_locals() {
        // push {r4-r7, lr}; sub sp, #24
        assert_eq!(prologue_bytes(&code(&[0xB5F0, 0xB086])), 5 * 4 + 24);
        // push.w {r4-r11, lr}; vpush {d8-d9}; subw sp, sp, #1844
        // (0xF2AD 0x7D34: i = 0, imm3 = 7, imm8 = 0x34: 0x734)
        assert_eq!(prologue_bytes(&code(&[0xE92D, 0x4FF0, 0xED2D, 0x8B04, 0xF2AD, 0x7D34])), 9 * 4 + 16 + 1844);
        // sub.w sp, sp, #29568: 29568 = 0x7380 = 0xE7 rotated right by 25
        // (imm12 = 25 << 7 | 0x67 = 0xCE7: i = 1, imm3 = 4, imm8 = 0xE7).
        assert_eq!(thumb_expand_imm(0xCE7), 29568);
        assert_eq!(prologue_bytes(&code(&[0xF5AD, 0x4DE7])), 29568);
        // A size no immediate encodes: movw r12, #0x1235; movt r12, #1;
        // sub.w sp, sp, r12.
        assert_eq!(prologue_bytes(&code(&[0xF241, 0x2C35, 0xF2C0, 0x0C01, 0xEBAD, 0x0D0C])), 0x1_1235);
        // No stack: a leaf that only moves registers (mov r0, r1; bx lr).
        assert_eq!(prologue_bytes(&code(&[0x4608, 0x4770])), 0);
    }

    #[test]
    fn modified_immediates_expand_as_the_architecture_says() {
        assert_eq!(thumb_expand_imm(0x0AB), 0xAB);
        assert_eq!(thumb_expand_imm(0x1AB), 0x00AB_00AB);
        assert_eq!(thumb_expand_imm(0x2AB), 0xAB00_AB00);
        assert_eq!(thumb_expand_imm(0x3AB), 0xABAB_ABAB);
        // 1:imm12[6:0] rotated right by imm12[11:7].
        assert_eq!(thumb_expand_imm(0x400), 0x8000_0000);
        assert_eq!(thumb_expand_imm(0x47F), 0xFF00_0000);
    }
}
