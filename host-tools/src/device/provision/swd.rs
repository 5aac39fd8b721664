//! Factory provisioning over SWD: the calibration slot image a device would
//! write itself, composed on the host and written with the probe-rs CLI.
//!
//! One source of truth for each fact the device also uses:
//! - the flash map comes from the repository's `memory.x` (the firmware's
//!   linker script), parsed once in [`crate::device::memory_map`];
//! - the slot header is the calibration store's (`brdf_meter::store`, slot
//!   format version 1), cross-checked in the tests by opening the written
//!   flash with the library's own `Store`;
//! - the signed calibration's signature is checked against the keys the
//!   firmware trusts (`brdf_meter::signed`) and the blob is validated with
//!   `brdf_meter::blob::BlobView::parse`, the device's parser, before
//!   anything is written (the device checks both again at boot).
//!
//! Which slot: the one that does not hold the device's newest valid
//! calibration, with the next sequence number, exactly as the device's store
//! would choose; so a failed or interrupted SWD write leaves the previous
//! calibration in place and active.
use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, Result, bail, ensure};
use brdf_meter::blob::{BlobView, CRC32};
use brdf_meter::store::{SLOT_HEADER_LEN, decode_slot_header, encode_slot_header, newer};

use crate::device::memory_map::SlotMap;

/// probe-rs's name for the board's chip.
pub const CHIP: &str = "STM32L475VGTx";

/// A valid slot found on the device (the store's own slot description).
pub use brdf_meter::store::SlotInfo as Found;

/// The store's slot header for a blob (slot format version 1).
pub fn slot_header(sequence: u32, blob: &[u8]) -> [u8; SLOT_HEADER_LEN] {
    encode_slot_header(sequence, blob.len() as u32, CRC32.checksum(blob))
}

/// Parses a slot header; `None` unless magic, version, length and CRC hold.
pub fn parse_header(slot: u8, h: &[u8]) -> Option<Found> {
    decode_slot_header(slot, h)
}

/// Where a new blob goes: the slot not holding the newest valid calibration,
/// with the next sequence number; slot A with sequence 1 on a blank device.
/// `force` picks the slot; the sequence still exceeds every valid one, so the
/// new blob becomes the active calibration.
pub fn plan(found: &[Found], force: Option<u8>) -> (u8, u32) {
    let newest = found.iter().copied().reduce(|x, y| if newer(y.sequence, x.sequence) { y } else { x });
    let sequence = newest.map_or(1, |n| n.sequence.wrapping_add(1));
    let slot = force.unwrap_or(match newest {
        Some(n) => 1 - n.slot,
        None => 0,
    });
    (slot, sequence)
}

/// Flash program granularity of the STM32L4 (bytes).
pub const WRITE_UNIT: usize = brdf_meter::shape::FLASH_WRITE;

/// The bytes to write at a slot's start: header, signed calibration (`blob`:
/// the blob and its signature trailer), padded with erased bytes (0xFF) to
/// whole flash write units.
pub fn slot_image(sequence: u32, blob: &[u8], slot_len: u32) -> Result<Vec<u8>> {
    let unsigned = crate::calibration::signing::check_signed(
        blob,
        "the calibration",
        crate::calibration::signing::Signed::Calibration,
    )?;
    let view =
        BlobView::parse(unsigned).map_err(|e| anyhow::anyhow!("the blob would be refused by the device: {e}"))?;
    ensure!(
        view.as_bytes().len() == unsigned.len(),
        "the file has {} bytes between the blob and its signature",
        unsigned.len() - view.as_bytes().len()
    );
    let mut image = Vec::with_capacity(SLOT_HEADER_LEN + blob.len() + WRITE_UNIT);
    image.extend_from_slice(&slot_header(sequence, blob));
    image.extend_from_slice(blob);
    while image.len() % WRITE_UNIT != 0 {
        image.push(0xFF);
    }
    ensure!(
        image.len() <= slot_len as usize,
        "slot image of {} bytes does not fit a {}-byte calibration slot",
        image.len(),
        slot_len
    );
    Ok(image)
}

/// Runs the probe-rs command line.
#[derive(Clone, Debug)]
pub struct ProbeRs {
    /// The probe-rs executable.
    pub program: PathBuf,
    /// Chip name.
    pub chip: String,
    /// Probe selector (`VID:PID[:serial]`), when several are attached.
    pub probe: Option<String>,
    /// Scratch directory for the image and read-back files.
    pub scratch: PathBuf,
}

impl ProbeRs {
    fn base(&self, sub: &str) -> Command {
        let mut c = Command::new(&self.program);
        c.arg(sub).arg("--chip").arg(&self.chip).arg("--non-interactive");
        if let Some(p) = &self.probe {
            c.arg("--probe").arg(p);
        }
        c
    }

    fn run(&self, mut c: Command, what: &str) -> Result<()> {
        let out = c.output().with_context(|| {
            format!("cannot run {} (install probe-rs, or pass --probe-rs PATH)", self.program.display())
        })?;
        if !out.status.success() {
            bail!("probe-rs {what} failed ({}): {}", out.status, String::from_utf8_lossy(&out.stderr).trim());
        }
        Ok(())
    }

    /// Reads `len` bytes of target memory at `addr`.
    pub fn read(&self, addr: u32, len: usize) -> Result<Vec<u8>> {
        let file = self.scratch.join(format!("read-{addr:08x}-{len}.bin"));
        let mut c = self.base("read");
        c.arg("b8").arg(format!("{addr:#010x}")).arg(len.to_string());
        c.arg("--output").arg(&file).arg("--format").arg("binary");
        self.run(c, &format!("read of {len} bytes at {addr:#010x}"))?;
        let data = std::fs::read(&file).with_context(|| format!("probe-rs read wrote no {}", file.display()))?;
        ensure!(data.len() == len, "probe-rs read returned {} bytes, asked for {len}", data.len());
        Ok(data)
    }

    /// Writes `image` to flash at `addr` (probe-rs erases the pages it needs).
    pub fn download(&self, addr: u32, image: &[u8]) -> Result<()> {
        let file = self.scratch.join(format!("image-{addr:08x}.bin"));
        std::fs::write(&file, image).with_context(|| format!("cannot write {}", file.display()))?;
        let mut c = self.base("download");
        c.arg("--binary-format").arg("bin").arg("--base-address").arg(format!("{addr:#010x}"));
        c.arg(&file);
        self.run(c, &format!("download of {} bytes to {addr:#010x}", image.len()))
    }
}

/// Reads the device's slots and returns the valid ones (header and blob CRC,
/// as the device's store checks at boot).
pub fn scan(probe: &ProbeRs, map: &SlotMap) -> Result<Vec<Found>> {
    let mut found = Vec::new();
    for slot in 0..2u8 {
        let addr = map.addr(slot);
        let header = probe.read(addr, SLOT_HEADER_LEN)?;
        let Some(f) = parse_header(slot, &header) else { continue };
        if f.blob_len as u64 > (map.slot_len() as u64 - SLOT_HEADER_LEN as u64) {
            continue;
        }
        let blob = probe.read(addr + SLOT_HEADER_LEN as u32, f.blob_len as usize)?;
        if CRC32.checksum(&blob) == f.blob_crc {
            found.push(f);
        }
    }
    Ok(found)
}

/// What [`provision`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Provisioned {
    /// Slot written (0 = A, 1 = B).
    pub slot: u8,
    /// Its address.
    pub addr: u32,
    /// Sequence number given.
    pub sequence: u32,
    /// Bytes written.
    pub len: usize,
}

/// Writes `blob` into the device's calibration flash and verifies it by
/// reading it back.
pub fn provision(probe: &ProbeRs, map: &SlotMap, blob: &[u8], force: Option<u8>) -> Result<Provisioned> {
    // Refuse a bad blob before touching the device.
    let _ = slot_image(1, blob, map.slot_len())?;
    let found = scan(probe, map)?;
    let (slot, sequence) = plan(&found, force);
    let image = slot_image(sequence, blob, map.slot_len())?;
    let addr = map.addr(slot);
    probe.download(addr, &image)?;
    let back = probe.read(addr, image.len())?;
    if back != image {
        let at = back.iter().zip(&image).position(|(a, b)| a != b).unwrap_or(0);
        bail!("read-back differs from what was written at {:#010x}: the slot is not valid", addr as usize + at);
    }
    Ok(Provisioned { slot, addr, sequence, len: image.len() })
}

/// Writes the slot image for slot A of a blank device (sequence 1) to
/// `out`, atomically, for any programmer; returns the image's length and
/// the address it belongs at. Touches no device.
pub fn write_slot_image(blob: &[u8], out: &Path) -> Result<(usize, u32)> {
    let map = SlotMap::board();
    let image = slot_image(1, blob, map.slot_len())?;
    crate::output::io::write_atomic(out, &image)?;
    Ok((image.len(), map.addr(0)))
}

/// A scratch directory that lives as long as the value.
pub fn scratch_dir() -> Result<tempfile::TempDir> {
    tempfile::Builder::new().prefix("brdf-swd-").tempdir().context("cannot create a scratch directory")
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use brdf_meter::platform::host_sim::SimFlash;
    use brdf_meter::store::Store;

    /// A small valid blob whose contents depend on `seed` (the library's
    /// test-blob builder, n = 9, m = 3, 2 zones, 4 pixels), signed with the
    /// development key.
    pub(crate) fn test_blob(seed: f32) -> Vec<u8> {
        brdf_meter::test_blobs::signed_test_blob(9, 3, 2, 4, seed)
    }

    /// The blob of a signed calibration (without its trailer).
    fn unsigned(image: &[u8]) -> Vec<u8> {
        image[..image.len() - brdf_meter::signed::TRAILER_LEN].to_vec()
    }

    /// Opens the calibration region `cal` (slot A then slot B) with the
    /// device's store and returns the active blob and its sequence number.
    fn device_boot(cal: Vec<u8>, slot_len: u32) -> Option<(u8, u32, Vec<u8>)> {
        let store =
            Store::open(SimFlash::with_contents(cal), slot_len, brdf_meter::test_blobs::dev_trusted(), |_| true);
        let (info, view) = store.active_blob()?;
        Some((info.slot, info.sequence, view.as_bytes().to_vec()))
    }

    #[test]
    fn the_plan_targets_the_slot_without_the_newest_calibration() {
        let f = |slot, sequence| Found { slot, sequence, blob_len: 1, blob_crc: 0 };
        assert_eq!(plan(&[], None), (0, 1));
        assert_eq!(plan(&[f(0, 1)], None), (1, 2));
        assert_eq!(plan(&[f(1, 7)], None), (0, 8));
        assert_eq!(plan(&[f(0, 5), f(1, 6)], None), (0, 7));
        assert_eq!(plan(&[f(0, 9), f(1, 6)], None), (1, 10));
        // Wrapping: 0 is newer than u32::MAX.
        assert_eq!(plan(&[f(0, u32::MAX), f(1, 0)], None), (0, 1));
        assert_eq!(plan(&[f(0, 3)], Some(0)), (0, 4));
    }

    #[test]
    fn slot_image_is_the_stores_format_and_the_device_boots_it() {
        let slot_len = 8 * 2048;
        let (b1, b2) = (test_blob(1.0), test_blob(2.0));
        let mut cal = vec![0xFFu8; 2 * slot_len as usize];
        assert_eq!(device_boot(cal.clone(), slot_len), None, "blank flash has no calibration");
        let img1 = slot_image(1, &b1, slot_len).unwrap();
        assert_eq!(img1.len() % WRITE_UNIT, 0);
        assert_eq!(&img1[SLOT_HEADER_LEN..SLOT_HEADER_LEN + b1.len()], &b1[..]);
        cal[..img1.len()].copy_from_slice(&img1);
        assert_eq!(device_boot(cal.clone(), slot_len), Some((0, 1, unsigned(&b1))));
        // The next one goes to B with sequence 2, and wins.
        let found = [parse_header(0, &cal[..SLOT_HEADER_LEN]).unwrap()];
        let (slot, seq) = plan(&found, None);
        assert_eq!((slot, seq), (1, 2));
        let img2 = slot_image(seq, &b2, slot_len).unwrap();
        cal[slot_len as usize..slot_len as usize + img2.len()].copy_from_slice(&img2);
        assert_eq!(device_boot(cal.clone(), slot_len), Some((1, 2, unsigned(&b2))));
        // A torn write of B (one blob byte wrong) falls back to A.
        cal[slot_len as usize + SLOT_HEADER_LEN + 10] ^= 0x40;
        assert_eq!(device_boot(cal, slot_len), Some((0, 1, unsigned(&b1))));
    }

    #[test]
    fn bad_blobs_and_oversized_images_are_refused_before_any_write() {
        let mut b = test_blob(1.0);
        assert!(slot_image(1, &b, brdf_meter::shape::board::SLOT_LEN).is_ok());
        assert!(slot_image(1, &b, 64).is_err(), "must not fit a 64-byte slot");
        let mut longer = b.clone();
        longer.push(0);
        assert!(slot_image(1, &longer, brdf_meter::shape::board::SLOT_LEN).is_err(), "trailing bytes are refused");
        let e = slot_image(1, &unsigned(&b), brdf_meter::shape::board::SLOT_LEN).unwrap_err().to_string();
        assert!(e.contains("not signed"), "{e}");
        b[70] ^= 1;
        let e = slot_image(1, &b, brdf_meter::shape::board::SLOT_LEN).unwrap_err().to_string();
        assert!(e.contains("refused") && e.contains("does not verify"), "{e}");
        let mut corrupt = unsigned(&test_blob(1.0));
        corrupt[70] ^= 1;
        let e = slot_image(
            1,
            &crate::calibration::signing::sign_with_dev_key(&corrupt),
            brdf_meter::shape::board::SLOT_LEN,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("refused by the device"), "{e}");
        assert!(parse_header(0, &[0xFF; SLOT_HEADER_LEN]).is_none());
    }

    /// A stand-in for the probe-rs CLI: `download` and `read` on a file that
    /// plays the chip's flash (0x0800_0000..+1 MiB), logging each call. With
    /// FAKE_CORRUPT set, reads return one flipped byte.
    const FAKE_PROBE_RS: &str = r#"#!/usr/bin/env bash
set -euo pipefail
echo "$*" >> "$FAKE_LOG"
sub=$1; shift
chip=""; fmt=""; base=""; out=""; ofmt=""; pos=()
while [ $# -gt 0 ]; do
  case "$1" in
    --chip) chip=$2; shift 2;;
    --binary-format) fmt=$2; shift 2;;
    --base-address) base=$2; shift 2;;
    --output) out=$2; shift 2;;
    --format) ofmt=$2; shift 2;;
    --non-interactive) shift;;
    --probe) shift 2;;
    *) pos+=("$1"); shift;;
  esac
done
[ "$chip" = STM32L475VGTx ] || { echo "wrong chip '$chip'" >&2; exit 2; }
case "$sub" in
  download)
    [ "$fmt" = bin ] || { echo "need --binary-format bin" >&2; exit 2; }
    off=$(( base - 0x08000000 ))
    dd if="${pos[0]}" of="$FAKE_FLASH" bs=65536 seek=$off oflag=seek_bytes conv=notrunc status=none;;
  read)
    [ "${pos[0]}" = b8 ] && [ "$ofmt" = binary ] || { echo "bad read args" >&2; exit 2; }
    off=$(( ${pos[1]} - 0x08000000 )); len=${pos[2]}
    dd if="$FAKE_FLASH" of="$out" bs=65536 skip=$off count=$len iflag=skip_bytes,count_bytes status=none
    if [ -n "${FAKE_CORRUPT:-}" ] && [ "$len" -gt 40 ]; then
      printf '\x00' | dd of="$out" bs=1 seek=40 conv=notrunc status=none
    fi;;
  *) echo "unknown subcommand $sub" >&2; exit 2;;
esac
"#;

    struct Fake {
        dir: tempfile::TempDir,
        probe: ProbeRs,
    }

    impl Fake {
        fn new() -> Self {
            use std::os::unix::fs::PermissionsExt;
            let dir = tempfile::tempdir().unwrap();
            let exe = dir.path().join("probe-rs");
            std::fs::write(&exe, FAKE_PROBE_RS).unwrap();
            std::fs::set_permissions(&exe, std::fs::Permissions::from_mode(0o755)).unwrap();
            std::fs::write(dir.path().join("flash.bin"), vec![0xFFu8; 1 << 20]).unwrap();
            let scratch = dir.path().join("scratch");
            std::fs::create_dir(&scratch).unwrap();
            let probe = ProbeRs { program: exe, chip: CHIP.into(), probe: None, scratch };
            Self { dir, probe }
        }

        /// The fake's environment goes on the command, not the process, so
        /// tests can run in parallel.
        fn probe(&self, corrupt: bool) -> ProbeRsWithEnv<'_> {
            ProbeRsWithEnv { fake: self, corrupt }
        }

        fn flash(&self) -> Vec<u8> {
            std::fs::read(self.dir.path().join("flash.bin")).unwrap()
        }

        fn log(&self) -> String {
            std::fs::read_to_string(self.dir.path().join("log")).unwrap_or_default()
        }
    }

    struct ProbeRsWithEnv<'a> {
        fake: &'a Fake,
        corrupt: bool,
    }

    impl ProbeRsWithEnv<'_> {
        fn provision(&self, blob: &[u8], force: Option<u8>) -> Result<Provisioned> {
            // Wrap the fake in a tiny launcher that sets its environment.
            let launcher = self.fake.dir.path().join(if self.corrupt { "probe-rs-corrupt" } else { "probe-rs-env" });
            let script = format!(
                "#!/usr/bin/env bash\nexport FAKE_FLASH='{}' FAKE_LOG='{}' {}\nexec '{}' \"$@\"\n",
                self.fake.dir.path().join("flash.bin").display(),
                self.fake.dir.path().join("log").display(),
                if self.corrupt { "FAKE_CORRUPT=1" } else { "" },
                self.fake.probe.program.display()
            );
            std::fs::write(&launcher, script).unwrap();
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&launcher, std::fs::Permissions::from_mode(0o755)).unwrap();
            let probe = ProbeRs { program: launcher, ..self.fake.probe.clone() };
            provision(&probe, &SlotMap::board(), blob, force)
        }
    }

    fn cal_region(flash: &[u8]) -> Vec<u8> {
        let m = SlotMap::board();
        let start = (m.a.origin - 0x0800_0000) as usize;
        flash[start..start + 2 * m.slot_len() as usize].to_vec()
    }

    #[test]
    fn provisioning_through_probe_rs_alternates_slots_and_the_device_boots_the_newest() {
        let fake = Fake::new();
        let (b1, b2, b3) = (test_blob(1.0), test_blob(2.0), test_blob(3.0));
        let p1 = fake.probe(false).provision(&b1, None).unwrap();
        assert_eq!((p1.slot, p1.addr, p1.sequence), (0, brdf_meter::shape::board::SLOT_A, 1));
        let p2 = fake.probe(false).provision(&b2, None).unwrap();
        assert_eq!((p2.slot, p2.addr, p2.sequence), (1, brdf_meter::shape::board::SLOT_B, 2));
        let slot_len = SlotMap::board().slot_len();
        assert_eq!(device_boot(cal_region(&fake.flash()), slot_len), Some((1, 2, unsigned(&b2))));
        let p3 = fake.probe(false).provision(&b3, None).unwrap();
        assert_eq!((p3.slot, p3.sequence), (0, 3));
        assert_eq!(device_boot(cal_region(&fake.flash()), slot_len), Some((0, 3, unsigned(&b3))));
        // Everything below the calibration slots (bootloader, images,
        // recipes) was never touched.
        let below = (brdf_meter::shape::board::SLOT_A - brdf_meter::shape::FLASH_BASE) as usize;
        assert!(fake.flash()[..below].iter().all(|&b| b == 0xFF));
        let log = fake.log();
        assert!(
            log.contains(
                "download --chip STM32L475VGTx --non-interactive --binary-format bin --base-address 0x08060000"
            ),
            "{log}"
        );
        assert!(log.contains("read --chip STM32L475VGTx --non-interactive b8 0x080b0000 32 --output"), "{log}");
    }

    #[test]
    fn a_read_back_mismatch_fails_and_a_forced_slot_is_honoured() {
        let fake = Fake::new();
        let b1 = test_blob(1.0);
        let e = fake.probe(true).provision(&b1, None).unwrap_err().to_string();
        assert!(e.contains("read-back differs"), "{e}");
        let p = fake.probe(false).provision(&b1, Some(1)).unwrap();
        assert_eq!((p.slot, p.addr), (1, brdf_meter::shape::board::SLOT_B));
    }

    #[test]
    fn a_missing_probe_rs_is_a_clear_error() {
        let dir = tempfile::tempdir().unwrap();
        let probe = ProbeRs {
            program: dir.path().join("no-such-probe-rs"),
            chip: CHIP.into(),
            probe: None,
            scratch: dir.path().to_path_buf(),
        };
        let e = format!("{:#}", provision(&probe, &SlotMap::board(), &test_blob(1.0), None).unwrap_err());
        assert!(e.contains("install probe-rs"), "{e}");
    }
}
