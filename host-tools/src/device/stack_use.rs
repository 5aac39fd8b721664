//! How much of its stack a firmware has used: the high-water mark of a
//! painted stack.
//!
//! The firmware images are built with cortex-m-rt's `paint-stack`: before
//! `main`, the reset handler fills the whole stack region (from
//! `_stack_end`, the start of SRAM1, up to `_stack_start`, where the
//! statics begin: memory.x's STACK) with [`PAINT`]. The stack grows down
//! from the top, so the lowest word that no longer holds the paint is as
//! deep as the stack has ever been. The firmware budget reserves [`crate::device::budget::STACK_RESERVE`]
//! for the stack; this is how the QEMU tests measure what the application
//! really takes (its tasks' poll frames, the estimation, the inspection,
//! the update's signature check) and hold it within that reserve.
//!
//! On a board the same region can be read through the probe (`probe-rs
//! read b32`, `docs/guide/board.md`) and its words looked at the same way.
use anyhow::{Context, anyhow};

/// cortex-m-rt's paint (`STACK_PAINT_VALUE`).
pub const PAINT: u32 = 0xcccc_cccc;

/// A firmware's stack region, from its ELF's symbols.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StackRegion {
    /// `_stack_end`: the lowest address the stack may reach (the start of
    /// SRAM1: below it, no memory).
    pub bottom: u32,
    /// `_stack_start`: the initial stack pointer (where the statics begin).
    pub top: u32,
}

impl StackRegion {
    /// The region of the firmware ELF `elf` (`name` for errors).
    pub fn of_elf(elf: &[u8], name: &str) -> anyhow::Result<Self> {
        use object::{Object as _, ObjectSymbol as _};
        let file = object::File::parse(elf).map_err(|e| anyhow!("{name}: not an ELF file: {e}"))?;
        let symbol = |s: &str| {
            file.symbols()
                .find(|x| x.name() == Ok(s))
                .map(|x| x.address() as u32)
                .with_context(|| format!("{name} has no symbol {s}: is it a cortex-m-rt firmware ELF (not stripped)?"))
        };
        let (bottom, top) = (symbol("_stack_end")?, symbol("_stack_start")?);
        if bottom > top || bottom % 4 != 0 {
            anyhow::bail!("{name}: stack region {bottom:#010x}..{top:#010x} is not a word-aligned range");
        }
        Ok(Self { bottom, top })
    }

    /// Its size in bytes.
    pub fn len(&self) -> u32 {
        self.top - self.bottom
    }

    /// Whether it is empty (no room was given to the stack).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// The stack's high-water mark.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StackUse {
    /// The region's size (bytes).
    pub size: u32,
    /// The deepest the stack has been (bytes below the top).
    pub used: u32,
}

impl StackUse {
    /// The high-water mark from the region's bytes `memory` (read from
    /// `region.bottom` on, little-endian words): the top less the lowest
    /// word without the paint. A region whose lowest word is not painted
    /// reads as used whole: the stack reached the end of its region, or the image
    /// was built without `paint-stack` (either way, nothing is known to be
    /// free).
    pub fn of(region: StackRegion, memory: &[u8]) -> anyhow::Result<Self> {
        let size = region.len();
        let bytes = memory
            .get(..size as usize)
            .with_context(|| format!("{} bytes of memory read for a stack of {size} bytes", memory.len()))?;
        let free_words =
            bytes.chunks_exact(4).take_while(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]) == PAINT).count();
        Ok(Self { size, used: size - 4 * free_words as u32 })
    }

    /// Bytes never reached.
    pub fn free(&self) -> u32 {
        self.size - self.used
    }
}

impl std::fmt::Display for StackUse {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} B of its {} B stack used at most ({} B never reached)", self.used, self.size, self.free())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn painted(size: usize, used: usize) -> Vec<u8> {
        let mut m: Vec<u8> = PAINT.to_le_bytes().iter().copied().cycle().take(size).collect();
        for (k, b) in m[size - used..].iter_mut().enumerate() {
            *b = k as u8;
        }
        m
    }

    #[test]
    fn the_high_water_mark_is_the_lowest_word_without_paint() {
        let r = StackRegion { bottom: 0x2000_1000, top: 0x2000_1400 };
        assert_eq!(StackUse::of(r, &painted(1024, 100)).unwrap(), StackUse { size: 1024, used: 100 });
        // A word partly scrubbed counts whole; a painted word between used
        // ones (a frame's hole) does not hide the deeper use.
        let mut m = painted(1024, 0);
        m[1024 - 301] = 0;
        assert_eq!(StackUse::of(r, &m).unwrap().used, 304);
        assert_eq!(StackUse::of(r, &painted(1024, 0)).unwrap().used, 0);
        // Reached the end of its region, or not painted at all: nothing is free.
        let full = StackUse::of(r, &painted(1024, 1024)).unwrap();
        assert_eq!((full.used, full.free()), (1024, 0));
        assert!(StackUse::of(r, &painted(1000, 0)).is_err(), "too few bytes read");
        assert_eq!(full.to_string(), "1024 B of its 1024 B stack used at most (0 B never reached)");
    }

    #[test]
    fn a_file_that_is_not_an_elf_has_no_region() {
        let e = StackRegion::of_elf(b"not an elf", "x.bin").unwrap_err().to_string();
        assert!(e.starts_with("x.bin: not an ELF file"), "{e}");
    }
}
