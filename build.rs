//! Link setup for the firmware binaries (only when building for a bare-metal
//! target; host builds of the library get nothing from here).
//!
//! - `memory.x` (repo root, on the linker search path) is the one flash map.
//!   cortex-m-rt's `link.x` links every image into the region named `FLASH`;
//!   memory.x includes `image-region.x` to say which region that is, and
//!   each binary gets its own, in its own folder of OUT_DIR on its own
//!   search path:
//!   - the applications (`board-fw`, `qemu-fw`, the board tests): ACTIVE;
//!   - the bootloader: BOOTLOADER;
//!   - the QEMU benches (kernel, line, verify, inspect) and the
//!     stack-overflow probe: the chip's flash from the reset vector to the
//!     end of ACTIVE, so QEMU runs them with no bootloader in front (they
//!     are measuring tools, never installed).
//! - `-Tlink.x` is passed to every binary of this package: on a bare-metal
//!   target all of them are firmware images.
//! - `-Tdefmt.x` only to `board-fw`, the one binary that links defmt (the QEMU
//!   firmware may not, and an unused defmt.x would fail its link), and with
//!   `-Tlink.x` to the board tests (test target `board-tests`, feature
//!   `board-tests`).
//!
//! - `trusted_keys.rs` in OUT_DIR: the public keys signed calibrations must
//!   verify against (src/signed.rs), from the file `BRDF_TRUSTED_KEYS` names
//!   (relative to the repository root, or absolute), or by default the
//!   DEVELOPMENT key `host-tools/keys/dev-NOT-FOR-PRODUCTION.pub`. A board
//!   build that trusts the development key gets a warning.
//!
//! Keeping the link arguments here rather than in `.cargo/config.toml`
//! rustflags means `RUSTFLAGS=-Dwarnings` (which replaces config rustflags)
//! cannot silently drop them.
use std::{env, fs, path::Path, path::PathBuf};

/// The development key's public half (its secret is checked in beside it).
const DEV_KEY: &str = "host-tools/keys/dev-NOT-FOR-PRODUCTION.pub";

/// The hex keys of a key file: one per line, `#` starts a comment.
fn read_keys(path: &Path) -> Vec<[u8; 32]> {
    let text = fs::read_to_string(path).unwrap_or_else(|e| panic!("trusted keys: cannot read {}: {e}", path.display()));
    let mut keys = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let hex = line.split('#').next().unwrap_or("").trim();
        if hex.is_empty() {
            continue;
        }
        let bad =
            || panic!("trusted keys: {}:{}: expected 64 hex digits (an Ed25519 public key)", path.display(), i + 1);
        if hex.len() != 64 || !hex.is_ascii() {
            bad();
        }
        let mut k = [0u8; 32];
        for (j, b) in k.iter_mut().enumerate() {
            *b = u8::from_str_radix(&hex[2 * j..2 * j + 2], 16).unwrap_or_else(|_| bad());
        }
        keys.push(k);
    }
    if keys.is_empty() {
        panic!("trusted keys: {} lists no key", path.display());
    }
    keys
}

fn trusted_keys(root: &Path) {
    println!("cargo:rerun-if-env-changed=BRDF_TRUSTED_KEYS");
    let dev_path = root.join(DEV_KEY);
    let path = env::var_os("BRDF_TRUSTED_KEYS").map_or_else(|| dev_path.clone(), |p| root.join(p));
    println!("cargo:rerun-if-changed={}", path.display());
    println!("cargo:rerun-if-changed={}", dev_path.display());
    let keys = read_keys(&path);
    let dev = read_keys(&dev_path);
    let trusts_dev = keys.iter().any(|k| dev.contains(k));
    if trusts_dev && env::var_os("CARGO_FEATURE_BOARD").is_some() {
        println!(
            "cargo:warning=this board firmware trusts the DEVELOPMENT calibration key (NOT FOR PRODUCTION): build with BRDF_TRUSTED_KEYS=your.pub"
        );
    }
    let list: Vec<String> = keys.iter().map(|k| format!("{k:?}")).collect();
    let code = format!(
        "/// The public keys a signed calibration must verify against (built in from\n\
         /// `{}`).\n\
         pub const TRUSTED_KEYS: &[PublicKeyBytes] = &[{}];\n\
         /// Whether this build trusts the DEVELOPMENT key (NOT FOR PRODUCTION).\n\
         pub const TRUSTS_DEVELOPMENT_KEY: bool = {trusts_dev};\n",
        path.strip_prefix(root).unwrap_or(&path).display(),
        list.join(", ")
    );
    let out = PathBuf::from(env::var("OUT_DIR").expect("cargo sets OUT_DIR")).join("trusted_keys.rs");
    fs::write(out, code).expect("writing trusted_keys.rs");
}

/// The firmware binaries that are applications: linked into the active image
/// region, started by the bootloader. A binary missing from these lists
/// fails to link (its linker finds no memory.x).
const APP_BINS: &[&str] = &["board-fw", "qemu-fw"];
/// The QEMU benches and the stack-overflow probe: linked from the reset
/// vector, run without a bootloader.
const BENCH_BINS: &[&str] = &["kernel-bench", "line-bench", "verify-bench", "inspect-bench", "stack-overflow-probe"];

/// Writes `OUT_DIR/region-<name>/image-region.x` (the file memory.x
/// includes to say which region is FLASH); returns the folder.
fn write_region(out: &Path, name: &str, script: &str) -> PathBuf {
    let dir = out.join(format!("region-{name}"));
    fs::create_dir_all(&dir).expect("creating a linker script folder in OUT_DIR");
    fs::write(dir.join("image-region.x"), format!("/* Generated by build.rs: {name} images. */\n{script}\n"))
        .expect("writing image-region.x");
    dir
}

/// The QEMU benches' FLASH: from the bootloader's origin to the end of the
/// active region, read from memory.x.
fn bench_region(memory_x: &str) -> String {
    let line = |n: &str| {
        memory_x
            .lines()
            .find(|l| l.split(':').next().unwrap_or("").trim() == n)
            .unwrap_or_else(|| panic!("memory.x has no region {n}"))
    };
    let (origin, _) = origin_length(line("BOOTLOADER"));
    let (active, active_len) = origin_length(line("ACTIVE"));
    format!("MEMORY {{ FLASH : ORIGIN = 0x{origin:08X}, LENGTH = {} }}", active + active_len - origin)
}

/// ORIGIN and LENGTH of one `NAME : ORIGIN = 0x.., LENGTH = ..K` line.
fn origin_length(line: &str) -> (u64, u64) {
    let field = |key: &str| {
        let v = line.split(',').find_map(|f| f.split_once('=').filter(|(k, _)| k.trim().ends_with(key)))?.1.trim();
        let (digits, mult) = match v.strip_suffix('K') {
            Some(d) => (d, 1024),
            None => (v, 1),
        };
        let n = match digits.strip_prefix("0x") {
            Some(h) => u64::from_str_radix(h, 16).ok()?,
            None => digits.parse().ok()?,
        };
        Some(n * mult)
    };
    match (field("ORIGIN"), field("LENGTH")) {
        (Some(o), Some(l)) => (o, l),
        _ => panic!("memory.x: cannot read ORIGIN and LENGTH of `{line}`"),
    }
}

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=memory.x");
    let root = PathBuf::from(env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    trusted_keys(&root);
    if env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("none") {
        return;
    }
    // memory.x itself is found in the linker's working directory (the
    // package root); each binary's image-region.x on its own search path.
    let memory_x = fs::read_to_string(root.join("memory.x")).expect("reading memory.x");
    let out = PathBuf::from(env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    let app = write_region(&out, "application", "REGION_ALIAS(\"FLASH\", ACTIVE);");
    let boot = write_region(&out, "bootloader", "REGION_ALIAS(\"FLASH\", BOOTLOADER);");
    let bench = write_region(&out, "bench", &bench_region(&memory_x));
    println!("cargo:rustc-link-search={}", root.display());
    for bin in APP_BINS {
        println!("cargo:rustc-link-arg-bin={bin}=-L{}", app.display());
    }
    println!("cargo:rustc-link-arg-bin=bootloader=-L{}", boot.display());
    for bin in BENCH_BINS {
        println!("cargo:rustc-link-arg-bin={bin}=-L{}", bench.display());
    }
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    // Without it lld puts the ELF headers in a loadable segment at the start
    // of the 64 KiB page below an image that does not start on one (ACTIVE):
    // in the bootloader's region, where a loader would write them.
    println!("cargo:rustc-link-arg-bins=--nmagic");
    if env::var_os("CARGO_FEATURE_BOARD").is_some() {
        println!("cargo:rustc-link-arg-bin=board-fw=-Tdefmt.x");
    }
    // The board tests (the package's one test target, built only for the
    // chip with feature board-tests) link like the board firmware.
    if env::var_os("CARGO_FEATURE_BOARD_TESTS").is_some() {
        println!("cargo:rustc-link-arg-tests=-L{}", app.display());
        println!("cargo:rustc-link-arg-tests=-Tlink.x");
        println!("cargo:rustc-link-arg-tests=--nmagic");
        println!("cargo:rustc-link-arg-tests=-Tdefmt.x");
    }
}
