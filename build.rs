//! Link setup for the firmware binaries (only when building for a bare-metal
//! target; host builds of the library get nothing from here).
//!
//! - `memory.x` (repo root) is put on the linker search path so cortex-m-rt's
//!   `link.x` finds it.
//! - `-Tlink.x` is passed to every binary of this package: on a bare-metal
//!   target all of them are firmware images.
//! - `-Tdefmt.x` only to `board-fw`, the one binary that links defmt (the QEMU
//!   firmware may not, and an unused defmt.x would fail its link).
//!
//! Keeping the link arguments here rather than in `.cargo/config.toml`
//! rustflags means `RUSTFLAGS=-Dwarnings` (which replaces config rustflags)
//! cannot silently drop them.
use std::{env, path::PathBuf};

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=memory.x");
    if env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("none") {
        return;
    }
    let root = PathBuf::from(env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    println!("cargo:rustc-link-search={}", root.display());
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    if env::var_os("CARGO_FEATURE_BOARD").is_some() {
        println!("cargo:rustc-link-arg-bin=board-fw=-Tdefmt.x");
    }
}
