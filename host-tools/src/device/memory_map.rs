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

/// The board's memory map: the firmware's regions and the calibration slots.
#[derive(Clone, Copy, Debug)]
pub struct MemoryMap {
    /// Firmware image region.
    pub flash: Region,
    /// Calibration slot A.
    pub slot_a: Region,
    /// Calibration slot B.
    pub slot_b: Region,
    /// Main RAM (statics and stack).
    pub ram: Region,
}

impl MemoryMap {
    /// Reads the regions of a linker script.
    pub fn from_script(script: &str) -> Result<Self> {
        Ok(Self {
            flash: region(script, "FLASH")?,
            slot_a: region(script, "CAL_SLOT_A")?,
            slot_b: region(script, "CAL_SLOT_B")?,
            ram: region(script, "RAM")?,
        })
    }

    /// The board's map (this repository's memory.x), checked against the
    /// library's `shape::board`, which the firmware and the store use.
    pub fn board() -> Self {
        use brdf_meter::shape::{self, board};
        let m = Self::from_script(MEMORY_X).expect("memory.x defines FLASH, CAL_SLOT_A, CAL_SLOT_B and RAM");
        assert_eq!(
            (
                m.flash.origin,
                m.flash.length,
                m.slot_a.origin,
                m.slot_b.origin,
                m.slot_a.length,
                m.ram.origin,
                m.ram.length
            ),
            (
                shape::FLASH_BASE,
                board::IMAGE_LEN,
                board::SLOT_A,
                board::SLOT_B,
                board::SLOT_LEN,
                board::RAM_ORIGIN,
                board::RAM_LEN
            ),
            "memory.x disagrees with brdf_meter::shape::board"
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
        let swapped = MEMORY_X.replace("CAL_SLOT_B : ORIGIN = 0x080A0000", "CAL_SLOT_B : ORIGIN = 0x080B0000");
        assert_ne!(swapped, MEMORY_X);
        assert!(SlotMap::from_script(&swapped).is_err(), "B not right after A must be refused");
    }

    #[test]
    fn memory_x_gives_the_documented_map() {
        let m = MemoryMap::board();
        assert_eq!((m.flash.origin, m.flash.length), (0x0800_0000, 256 * 1024));
        assert_eq!((m.slot_a.origin, m.slot_a.length), (0x0804_0000, 384 * 1024));
        assert_eq!((m.slot_b.origin, m.slot_b.length), (0x080A_0000, 384 * 1024));
        assert_eq!((m.ram.origin, m.ram.length), (0x2000_0000, 96 * 1024));
    }
}
