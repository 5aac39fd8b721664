//! `host-tools sign-firmware`: a firmware ELF into a signed update image.
use crate::calibration::signing;
use anyhow::{Context, bail, ensure};
use brdf_meter::firmware::image::{self, Target};
use brdf_meter::shape::board::{ACTIVE, ACTIVE_LEN};
use std::path::{Path, PathBuf};

/// Sign a firmware (the ELF `cargo board-fw` or `cargo qemu-fw` builds)
/// for updates over the link (`host-tools update-firmware`): writes its
/// flash image from the active region's start, padded to 8 bytes, followed
/// by a signed trailer (target, version, key id, Ed25519 signature).
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The secret key (`host-tools keygen`; the calibrations' keys).
    #[arg(long, value_name = "KEY")]
    pub key: PathBuf,
    /// The firmware ELF.
    #[arg(long, value_name = "ELF")]
    pub elf: PathBuf,
    /// The machine it is built for: board or qemu.
    #[arg(long, value_parser = ["board", "qemu"])]
    pub target: String,
    /// Its version, MAJOR.MINOR.PATCH (each 0..=255): by default the one the
    /// firmware reports (its `BRDF_FIRMWARE_VERSION` symbol); given, it must
    /// be that one.
    #[arg(long = "fw-version", value_name = "X.Y.Z")]
    pub version: Option<String>,
    /// Where to write the signed image.
    #[arg(long, value_name = "OUT")]
    pub out: PathBuf,
}

/// A version `X.Y.Z`.
pub fn parse_version(s: &str) -> anyhow::Result<[u8; 3]> {
    let parts: Vec<&str> = s.split('.').collect();
    ensure!(parts.len() == 3, "version `{s}` is not MAJOR.MINOR.PATCH");
    let mut v = [0u8; 3];
    for (d, p) in v.iter_mut().zip(parts) {
        *d = p.parse().with_context(|| format!("version `{s}`: `{p}` is not a number 0..=255"))?;
    }
    Ok(v)
}

/// The flash bytes of a firmware ELF, from the active region's start: every
/// loaded segment at its load address (so .data's initial values too).
pub fn flash_image(elf: &[u8], name: &str) -> anyhow::Result<Vec<u8>> {
    use object::read::elf::{ElfFile32, ProgramHeader as _};
    let file = ElfFile32::<object::LittleEndian>::parse(elf)
        .map_err(|e| anyhow::anyhow!("{name} is not a 32-bit little-endian ELF (a Cortex-M image): {e}"))?;
    let endian = file.endian();
    let mut out = Vec::new();
    for ph in file.elf_program_headers() {
        if ph.p_type(endian) != object::elf::PT_LOAD || ph.p_filesz(endian) == 0 {
            continue;
        }
        let (addr, size) = (ph.p_paddr(endian), ph.p_filesz(endian) as usize);
        if !(ACTIVE..ACTIVE + ACTIVE_LEN).contains(&addr) {
            bail!(
                "{name} loads {size} bytes at {addr:#010x}, outside the active image region ({ACTIVE:#010x}..{:#010x}): is it an application built by `cargo board-fw` / `cargo qemu-fw`?",
                ACTIVE + ACTIVE_LEN
            );
        }
        let data = ph.data(endian, elf).map_err(|()| anyhow::anyhow!("{name}: a segment lies outside the file"))?;
        let at = (addr - ACTIVE) as usize;
        if out.len() < at + size {
            out.resize(at + size, 0xFF);
        }
        out[at..at + size].copy_from_slice(data);
    }
    ensure!(out.len() >= 8, "{name} loads nothing into the active image region");
    Ok(out)
}

/// The `N` bytes of a firmware ELF's symbol `symbol` (a `#[no_mangle]`
/// static the firmware declares), read from its flash image. `None` for an
/// ELF without the symbol.
fn symbol_bytes<const N: usize>(elf: &[u8], flash: &[u8], name: &str, symbol: &str) -> anyhow::Result<Option<[u8; N]>> {
    use object::{Object as _, ObjectSymbol as _};
    let file = object::File::parse(elf).map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    let Some(sym) = file.symbols().find(|s| s.name() == Ok(symbol)) else {
        return Ok(None);
    };
    let at = (sym.address() as u32).wrapping_sub(ACTIVE) as usize;
    let b = flash
        .get(at..at + N)
        .with_context(|| format!("{name}: {symbol} at {:#010x} is not in the image's flash bytes", sym.address()))?;
    Ok(Some(b.try_into().expect("N bytes")))
}

/// The version a firmware ELF reports: the 3 bytes of its
/// `BRDF_FIRMWARE_VERSION` symbol. `None` for an ELF without the symbol.
pub fn elf_version(elf: &[u8], flash: &[u8], name: &str) -> anyhow::Result<Option<[u8; 3]>> {
    symbol_bytes(elf, flash, name, "BRDF_FIRMWARE_VERSION")
}

/// The machine a firmware ELF declares it is built for: its
/// `BRDF_FIRMWARE_TARGET` symbol (`Target::declared`). `None` for an ELF
/// without the symbol.
pub fn elf_target(elf: &[u8], flash: &[u8], name: &str) -> anyhow::Result<Option<Target>> {
    let Some(b) = symbol_bytes::<4>(elf, flash, name, "BRDF_FIRMWARE_TARGET")? else {
        return Ok(None);
    };
    let code = u32::from_le_bytes(b);
    Target::from_code(code)
        .map(Some)
        .with_context(|| format!("{name}: BRDF_FIRMWARE_TARGET holds {code}, no target's code"))
}

/// Signs the ELF at `elf` (see [`Args`]) with `version`, or the version the
/// firmware reports when `None`; refused when the ELF declares another
/// target than `target`.
pub fn sign_elf(elf: &Path, target: Target, version: Option<[u8; 3]>, seed: &[u8; 32]) -> anyhow::Result<Vec<u8>> {
    let name = elf.display().to_string();
    let bytes = std::fs::read(elf).with_context(|| format!("reading {name}"))?;
    let flash = flash_image(&bytes, &name)?;
    if let Some(own) = elf_target(&bytes, &flash, &name)?
        && own != target
    {
        bail!("{name} is built for {own:?}, not {target:?}: sign it with --target {}", target_arg(own));
    }
    let version = match (version, elf_version(&bytes, &flash, &name)?) {
        (Some(given), Some(own)) if given != own => bail!(
            "{name} reports firmware {}.{}.{}, not {}.{}.{}: a device would show another version than the one signed (bump FIRMWARE_VERSION in src/app/mod.rs and rebuild, or leave out --fw-version)",
            own[0],
            own[1],
            own[2],
            given[0],
            given[1],
            given[2]
        ),
        (_, Some(own)) => own,
        (Some(given), None) => given,
        (None, None) => bail!("{name} has no BRDF_FIRMWARE_VERSION symbol: give its version with --fw-version X.Y.Z"),
    };
    let words = [0, 4].map(|o| u32::from_le_bytes([flash[o], flash[o + 1], flash[o + 2], flash[o + 3]]));
    ensure!(
        image::vector_table_fits(words, flash.len() as u32),
        "{name} does not start with a vector table for the active region (stack {:#x}, reset {:#x})",
        words[0],
        words[1]
    );
    let signed = image::sign(&flash, target, version, seed);
    ensure!(
        signed.len() <= ACTIVE_LEN as usize,
        "{name}'s signed image is {} bytes, more than the active region's {ACTIVE_LEN}",
        signed.len()
    );
    Ok(signed)
}

/// `--target`'s word for `t`.
fn target_arg(t: Target) -> &'static str {
    match t {
        Target::Board => "board",
        Target::Qemu => "qemu",
    }
}

/// Runs the command. Nothing is written unless the ELF and the key read.
pub fn run(a: Args) -> anyhow::Result<()> {
    let target = if a.target == "board" { Target::Board } else { Target::Qemu };
    let given = a.version.as_deref().map(parse_version).transpose()?;
    let seed = signing::read_secret(&a.key)?;
    let signed = sign_elf(&a.elf, target, given, &seed)?;
    let (manifest, _) = image::decode_trailer(
        signed[signed.len() - image::FW_TRAILER_LEN..].try_into().expect("a signed image ends with its trailer"),
        signed.len() as u32,
    )
    .map_err(|e| anyhow::anyhow!("the image just signed does not read back: {e}"))?;
    let version = manifest.version;
    crate::output::io::write_atomic(&a.out, &signed).with_context(|| format!("writing {}", a.out.display()))?;
    println!(
        "wrote {} ({} bytes, {:?} firmware {}.{}.{}, signed with {}{})",
        a.out.display(),
        signed.len(),
        target,
        version[0],
        version[1],
        version[2],
        a.key.display(),
        signing::untrusted_note(&seed)
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn versions_parse_and_bad_ones_say_why() {
        assert_eq!(parse_version("1.2.3").unwrap(), [1, 2, 3]);
        for bad in ["1.2", "1.2.3.4", "1.x.3", "1.2.256"] {
            assert!(parse_version(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn an_elf_that_is_not_an_application_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.elf");
        std::fs::write(&p, b"not an elf").unwrap();
        let e = sign_elf(&p, Target::Qemu, Some([1, 0, 0]), &[1; 32]).unwrap_err().to_string();
        assert!(e.contains("not a 32-bit"), "{e}");
    }
}
