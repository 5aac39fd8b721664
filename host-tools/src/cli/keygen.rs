//! `host-tools keygen`: a new key pair for signing calibrations.
use crate::calibration::signing;
use std::path::PathBuf;

/// Generate an Ed25519 key pair for signing calibrations: the secret to
/// `--out` (0600; keep it offline), the public key to the same name with
/// `.pub`, the file the firmware is built with (`BRDF_TRUSTED_KEYS`).
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The secret key file to write (NAME.key; NAME.pub is written beside it).
    #[arg(long, value_name = "KEY")]
    pub out: PathBuf,
    /// Replace existing key files.
    #[arg(long)]
    pub force: bool,
}

/// Runs the command.
pub fn run(a: Args) -> anyhow::Result<()> {
    let pk = signing::keygen(&a.out, a.force)?;
    let id: String = brdf_meter::signed::key_id(&pk).iter().map(|b| format!("{b:02x}")).collect();
    println!(
        "wrote {} (secret: keep it offline) and {} (key id {id})",
        a.out.display(),
        signing::public_path(&a.out).display()
    );
    println!(
        "build firmware that trusts it: BRDF_TRUSTED_KEYS={} cargo board-fw",
        signing::public_path(&a.out).display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keygen_refuses_to_overwrite_without_force() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("k.key");
        run(Args { out: out.clone(), force: false }).unwrap();
        let before = std::fs::read(&out).unwrap();
        let e = run(Args { out: out.clone(), force: false }).unwrap_err().to_string();
        assert!(e.contains("--force"), "{e}");
        assert_eq!(std::fs::read(&out).unwrap(), before);
        run(Args { out: out.clone(), force: true }).unwrap();
        assert_ne!(std::fs::read(&out).unwrap(), before);
    }
}
