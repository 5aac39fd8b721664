//! The board's memory map, from the firmware's linker script `memory.x`
//! (built into this tool), parsed here and only here: the SWD provisioning's
//! calibration slots and the firmware budget's regions both come from it.
use anyhow::{Context, Result, bail, ensure};

/// The firmware's linker script.
pub const MEMORY_X: &str = include_str!("../../../memory.x");

/// One `NAME : ORIGIN = .., LENGTH = ..` region of a linker script.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Region {
    /// Start address.
    pub origin: u32,
    /// Length in bytes.
    pub length: u32,
}

impl Region {
    /// One past the last address.
    pub fn end(&self) -> u64 {
        self.origin as u64 + self.length as u64
    }
}

fn parse_number(s: &str) -> Result<u32> {
    let s = s.trim();
    let (digits, mult) = match s.chars().last() {
        Some('K') | Some('k') => (&s[..s.len() - 1], 1024u64),
        Some('M') | Some('m') => (&s[..s.len() - 1], 1024 * 1024),
        _ => (s, 1),
    };
    let v = if let Some(hex) = digits.strip_prefix("0x").or_else(|| digits.strip_prefix("0X")) {
        u64::from_str_radix(hex, 16)
    } else {
        digits.parse::<u64>()
    }
    .with_context(|| format!("`{s}` is not a number"))?;
    u32::try_from(v * mult).with_context(|| format!("`{s}` does not fit 32 bits"))
}

/// Finds region `name` in the MEMORY block of linker script `script`.
pub fn region(script: &str, name: &str) -> Result<Region> {
    // Strip /* */ comments first: the header comment mentions region names.
    let mut text = String::with_capacity(script.len());
    let mut rest = script;
    while let Some(start) = rest.find("/*") {
        text.push_str(&rest[..start]);
        let end = rest[start..].find("*/").context("unterminated comment in linker script")?;
        rest = &rest[start + end + 2..];
    }
    text.push_str(rest);
    for line in text.lines() {
        let Some((lhs, rhs)) = line.split_once(':') else { continue };
        if lhs.trim() != name {
            continue;
        }
        let mut origin = None;
        let mut length = None;
        for field in rhs.split(',') {
            let Some((k, v)) = field.split_once('=') else { continue };
            match k.trim() {
                "ORIGIN" | "org" | "o" => origin = Some(parse_number(v)?),
                "LENGTH" | "len" | "l" => length = Some(parse_number(v)?),
                _ => {}
            }
        }
        return match (origin, length) {
            (Some(origin), Some(length)) => Ok(Region { origin, length }),
            _ => bail!("region {name} has no ORIGIN or LENGTH"),
        };
    }
    bail!("linker script has no region {name}")
}

/// The calibration slots of the board, from `memory.x`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SlotMap {
    /// Slot A.
    pub a: Region,
    /// Slot B.
    pub b: Region,
}

impl SlotMap {
    /// The slots of a memory map, checked for what the device's store
    /// assumes: equal lengths, B right after A.
    pub fn from_map(map: &MemoryMap) -> Result<Self> {
        let (a, b) = (map.slot_a, map.slot_b);
        ensure!(a.length == b.length, "CAL_SLOT_A and CAL_SLOT_B differ in length");
        ensure!(b.origin as u64 == a.end(), "CAL_SLOT_B does not follow CAL_SLOT_A");
        Ok(Self { a, b })
    }

    /// Reads the slots from a linker script (see [`SlotMap::from_map`]).
    pub fn from_script(script: &str) -> Result<Self> {
        Self::from_map(&MemoryMap::from_script(script)?)
    }

    /// The board's slots (this repository's memory.x, which agrees with the
    /// library's `shape::board`: [`MemoryMap::board`] checks it, as the
    /// firmware does at boot).
    pub fn board() -> Self {
        Self::from_map(&MemoryMap::board()).expect("memory.x defines two equal, adjacent calibration slots")
    }

    /// Address of slot 0 (A) or 1 (B).
    pub fn addr(&self, slot: u8) -> u32 {
        if slot == 0 { self.a.origin } else { self.b.origin }
    }

    /// Bytes per slot.
    pub fn slot_len(&self) -> u32 {
        self.a.length
    }
}

/// The board's memory map: every region of `memory.x`.
#[derive(Clone, Copy, Debug)]
pub struct MemoryMap {
    /// The bootloader's image region.
    pub bootloader: Region,
    /// embassy-boot's state partition.
    pub boot_state: Region,
    /// The active firmware image region (memory.x's ACTIVE).
    pub flash: Region,
    /// The update image (DFU) partition.
    pub dfu: Region,
    /// Inspection recipe slot A.
    pub recipe_a: Region,
    /// Inspection recipe slot B.
    pub recipe_b: Region,
    /// Calibration slot A.
    pub slot_a: Region,
    /// Calibration slot B.
    pub slot_b: Region,
    /// The stack, at the start of SRAM1.
    pub stack: Region,
    /// The statics, the rest of SRAM1 (memory.x's RAM, as cortex-m-rt
    /// names the region it places them in).
    pub ram: Region,
}

impl MemoryMap {
    /// Reads the regions of a linker script.
    pub fn from_script(script: &str) -> Result<Self> {
        Ok(Self {
            bootloader: region(script, "BOOTLOADER")?,
            boot_state: region(script, "BOOT_STATE")?,
            flash: region(script, "ACTIVE")?,
            dfu: region(script, "DFU")?,
            recipe_a: region(script, "RECIPE_SLOT_A")?,
            recipe_b: region(script, "RECIPE_SLOT_B")?,
            slot_a: region(script, "CAL_SLOT_A")?,
            slot_b: region(script, "CAL_SLOT_B")?,
            stack: region(script, "STACK")?,
            ram: region(script, "RAM")?,
        })
    }

    /// The flash regions in address order, with memory.x's names.
    pub fn flash_regions(&self) -> [(&'static str, Region); 8] {
        [
            ("BOOTLOADER", self.bootloader),
            ("BOOT_STATE", self.boot_state),
            ("ACTIVE", self.flash),
            ("DFU", self.dfu),
            ("RECIPE_SLOT_A", self.recipe_a),
            ("RECIPE_SLOT_B", self.recipe_b),
            ("CAL_SLOT_A", self.slot_a),
            ("CAL_SLOT_B", self.slot_b),
        ]
    }

    /// The board's map (this repository's memory.x), checked against the
    /// library's `shape::board`, which the firmware and the store use.
    pub fn board() -> Self {
        use brdf_meter::shape::board as b;
        let m = Self::from_script(MEMORY_X).expect("memory.x defines every region of the board's map");
        let r = |origin, length| Region { origin, length };
        let want = [
            r(b::BOOTLOADER, b::BOOTLOADER_LEN),
            r(b::BOOT_STATE, b::BOOT_STATE_LEN),
            r(b::ACTIVE, b::ACTIVE_LEN),
            r(b::DFU, b::DFU_LEN),
            r(b::RECIPE_SLOT_A, b::RECIPE_SLOT_LEN),
            r(b::RECIPE_SLOT_B, b::RECIPE_SLOT_LEN),
            r(b::SLOT_A, b::SLOT_LEN),
            r(b::SLOT_B, b::SLOT_LEN),
        ];
        for ((name, got), want) in m.flash_regions().into_iter().zip(want) {
            assert_eq!(got, want, "memory.x's {name} disagrees with brdf_meter::shape::board");
        }
        assert_eq!(m.stack, r(b::RAM_ORIGIN, b::STACK_LEN), "memory.x's STACK disagrees with brdf_meter::shape::board");
        assert_eq!(
            m.ram,
            r(b::RAM_ORIGIN + b::STACK_LEN, b::RAM_LEN - b::STACK_LEN),
            "memory.x's RAM is not the rest of brdf_meter::shape::board's SRAM1 after the stack"
        );
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn memory_x_slots_are_parsed_not_assumed() {
        let m = SlotMap::board();
        assert_eq!(m.addr(0), brdf_meter::shape::board::SLOT_A);
        assert_eq!(m.addr(1), brdf_meter::shape::board::SLOT_B);
        assert_eq!(m.slot_len(), brdf_meter::shape::board::SLOT_LEN);
        assert_eq!(parse_number("0x10").unwrap(), 16);
        assert_eq!(parse_number(" 2K").unwrap(), 2048);
        assert_eq!(parse_number("1M").unwrap(), 1 << 20);
        assert!(parse_number("zz").is_err());
        assert!(region(MEMORY_X, "NOPE").is_err());
        let swapped = MEMORY_X.replace("CAL_SLOT_B    : ORIGIN = 0x080B0000", "CAL_SLOT_B    : ORIGIN = 0x080B8000");
        assert_ne!(swapped, MEMORY_X);
        assert!(SlotMap::from_script(&swapped).is_err(), "B not right after A must be refused");
    }

    #[test]
    fn memory_x_gives_the_documented_map() {
        let m = MemoryMap::board();
        let kib = |o: u32, k: u32| Region { origin: o, length: k * 1024 };
        assert_eq!(
            m.flash_regions().map(|(_, r)| r),
            [
                kib(0x0800_0000, 24),
                kib(0x0800_6000, 4),
                kib(0x0800_7000, 160),
                kib(0x0802_F000, 164),
                kib(0x0805_8000, 16),
                kib(0x0805_C000, 16),
                kib(0x0806_0000, 320),
                kib(0x080B_0000, 320),
            ]
        );
        // SRAM1: the stack at its start, the statics after it.
        assert_eq!((m.stack.origin, m.stack.length), (0x2000_0000, 16 * 1024));
        assert_eq!((m.ram.origin, m.ram.length), (0x2000_4000, 80 * 1024));
        // Back to back, filling the chip's 1 MiB.
        let regions = m.flash_regions();
        for w in regions.windows(2) {
            assert_eq!(w[0].1.end(), w[1].1.origin as u64, "{} is not followed by {}", w[0].0, w[1].0);
        }
        assert_eq!(regions[7].1.end(), 0x0810_0000);
    }
}
