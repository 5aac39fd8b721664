//! `host-tools sign`: sign a calibration blob for provisioning.
use crate::calibration::signing;
use crate::device::provision::parse_blob;
use anyhow::Context;
use std::path::PathBuf;

/// Sign a calibration blob (as `host-tools train` writes it) with a secret
/// key: writes the blob followed by its signature trailer, which devices
/// built to trust the key's public half accept.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The secret key (`host-tools keygen`).
    #[arg(long, value_name = "KEY")]
    pub key: PathBuf,
    /// The unsigned calibration blob.
    #[arg(long, value_name = "IN")]
    pub blob: PathBuf,
    /// Where to write the signed calibration.
    #[arg(long, value_name = "OUT")]
    pub out: PathBuf,
}

/// Runs the command. Nothing is written unless the blob is valid and the key reads.
pub fn run(a: Args) -> anyhow::Result<()> {
    let blob = std::fs::read(&a.blob).with_context(|| format!("reading {}", a.blob.display()))?;
    let name = a.blob.display().to_string();
    if brdf_meter::signed::split(&blob).is_ok() {
        anyhow::bail!("{name} is already signed (sign the unsigned blob `host-tools train` wrote)");
    }
    let view = parse_blob(&blob, &name)?;
    anyhow::ensure!(
        view.as_bytes().len() == blob.len(),
        "{name} has {} bytes after the blob",
        blob.len() - view.as_bytes().len()
    );
    let seed = signing::read_secret(&a.key)?;
    let image = signing::sign_blob(&blob, &seed);
    crate::output::io::write_atomic(&a.out, &image).with_context(|| format!("writing {}", a.out.display()))?;
    println!(
        "wrote {} ({} bytes, signed with {}{})",
        a.out.display(),
        image.len(),
        a.key.display(),
        signing::untrusted_note(&seed)
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn signs_a_blob_that_provisioning_accepts_and_refuses_bad_input() {
        let dir = tempfile::tempdir().unwrap();
        let blob = brdf_meter::test_blobs::test_blob(9, 3, 1, 4, 1.0);
        let inp = dir.path().join("cal.blob");
        std::fs::write(&inp, &blob).unwrap();
        let out = dir.path().join("cal.signed");
        let args = |blob: &std::path::Path, out: &std::path::Path| Args {
            key: signing::dev_key_path(),
            blob: blob.into(),
            out: out.into(),
        };
        run(args(&inp, &out)).unwrap();
        let image = crate::device::provision::read_blob(&out).unwrap();
        assert_eq!(&image[..blob.len()], &blob[..]);
        // Signing a signed file, or a file that is not a blob, writes nothing.
        let again = dir.path().join("twice");
        assert!(run(args(&out, &again)).unwrap_err().to_string().contains("already signed"));
        std::fs::write(&inp, b"not a blob").unwrap();
        let e = run(args(&inp, &again)).unwrap_err().to_string();
        assert!(e.contains("not a valid calibration blob"), "{e}");
        assert!(!again.exists());
    }
}
