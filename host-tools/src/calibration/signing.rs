//! Signing calibrations: key files, key generation and the signed image
//! (blob + signature trailer, layout in `brdf_meter::signed`).
//!
//! Key files are text: `#` comment lines, then the key as 64 hex digits.
//! - `NAME.key`: the Ed25519 secret seed. Keep it offline; whoever holds it
//!   can calibrate every device that trusts its public half. Written 0600.
//! - `NAME.pub`: the public key, the file the firmware is built with
//!   (`BRDF_TRUSTED_KEYS=NAME.pub`); several keys may be listed, one a line.
//!
//! The DEVELOPMENT KEY - NOT FOR PRODUCTION is `host-tools/keys/dev-NOT-FOR-PRODUCTION.{key,pub}`:
//! its secret is checked in so the tests and the QEMU demo can sign, so it
//! proves nothing about who made a calibration.
use anyhow::{Context, bail};
use brdf_meter::signed::{self, PublicKeyBytes, SignatureFault};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The development key's secret file (NOT FOR PRODUCTION).
pub fn dev_key_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("keys/dev-NOT-FOR-PRODUCTION.key")
}

/// The DEVELOPMENT KEY's secret seed (NOT FOR PRODUCTION), the same file the
/// library's test blobs sign with.
pub const DEV_SECRET: [u8; 32] = brdf_meter::test_blobs::DEV_SECRET;

/// `blob` followed by its signature trailer made with `seed`.
pub fn sign_blob(blob: &[u8], seed: &[u8; 32]) -> Vec<u8> {
    let mut image = blob.to_vec();
    image.extend_from_slice(&signed::sign(blob, seed));
    image
}

/// `blob` signed with the DEVELOPMENT KEY (the QEMU demo and the tests).
pub fn sign_with_dev_key(blob: &[u8]) -> Vec<u8> {
    sign_blob(blob, &DEV_SECRET)
}

/// The hex keys of a key file's text (named `name` in errors).
fn parse_keys(text: &str, name: &str) -> anyhow::Result<Vec<[u8; 32]>> {
    let mut keys = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let hex = line.split('#').next().unwrap_or("").trim();
        if hex.is_empty() {
            continue;
        }
        let bytes = (hex.len() == 64 && hex.is_ascii())
            .then(|| (0..32).map(|j| u8::from_str_radix(&hex[2 * j..2 * j + 2], 16).ok()).collect::<Option<Vec<u8>>>())
            .flatten();
        let Some(bytes) = bytes else {
            bail!("{name}:{}: expected a key as 64 hex digits", i + 1);
        };
        keys.push(bytes.try_into().expect("32 bytes"));
    }
    if keys.is_empty() {
        bail!("{name} holds no key");
    }
    Ok(keys)
}

/// What `sign` and `sign-firmware` add to their report when firmware built
/// from this tree (its default keys) would not trust the secret `seed`.
pub fn untrusted_note(seed: &[u8; 32]) -> &'static str {
    if signed::TRUSTED_KEYS.contains(&signed::public_key(seed)) {
        ""
    } else {
        "; note: firmware built from this tree with its default keys does not trust this key"
    }
}

/// Reads a secret key file (exactly one key).
pub fn read_secret(path: &Path) -> anyhow::Result<[u8; 32]> {
    let text = std::fs::read_to_string(path).with_context(|| format!("reading the signing key {}", path.display()))?;
    let keys = parse_keys(&text, &path.display().to_string())?;
    if keys.len() != 1 {
        bail!("{} holds {} keys; a secret key file holds one", path.display(), keys.len());
    }
    Ok(keys[0])
}

/// Reads a public key file (one or more keys).
pub fn read_public(path: &Path) -> anyhow::Result<Vec<PublicKeyBytes>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading the public key file {}", path.display()))?;
    parse_keys(&text, &path.display().to_string())
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// The public key file next to secret key file `key` (`NAME.key` -> `NAME.pub`).
pub fn public_path(key: &Path) -> PathBuf {
    key.with_extension("pub")
}

/// Writes `text` to `path` atomically with owner-only permissions (the
/// temporary file is created 0600 and renamed over the target).
fn write_private(path: &Path, text: &str) -> anyhow::Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    std::fs::create_dir_all(dir).with_context(|| format!("creating directory {}", dir.display()))?;
    let mut tmp = tempfile::NamedTempFile::new_in(dir)
        .with_context(|| format!("creating a temporary file in {}", dir.display()))?;
    tmp.write_all(text.as_bytes()).with_context(|| format!("writing {}", path.display()))?;
    tmp.as_file().sync_all().with_context(|| format!("flushing {}", path.display()))?;
    tmp.persist(path).with_context(|| format!("replacing {}", path.display()))?;
    Ok(())
}

/// Generates a key pair from the operating system's random source and
/// writes `key` (secret) and its `.pub` beside it. Refuses to replace either
/// file unless `force`. Returns the public key.
pub fn keygen(key: &Path, force: bool) -> anyhow::Result<PublicKeyBytes> {
    let public = public_path(key);
    if key.extension().is_some_and(|e| e == "pub") {
        bail!("{}: name the secret key file (NAME.key); its public half goes to NAME.pub", key.display());
    }
    for p in [key, public.as_path()] {
        if p.exists() && !force {
            bail!("{} exists: refusing to overwrite a key (pass --force to replace it)", p.display());
        }
    }
    let mut seed = [0u8; 32];
    getrandom::fill(&mut seed).map_err(|e| anyhow::anyhow!("the operating system's random source failed: {e}"))?;
    let pk = signed::public_key(&seed);
    write_private(
        key,
        &format!(
            "# Ed25519 secret key for signing BRDF meter calibrations (host-tools sign / train --sign).\n\
             # Keep it offline: whoever holds it can calibrate every device that trusts {}.\n{}\n",
            public.display(),
            hex(&seed)
        ),
    )?;
    crate::output::io::write_atomic(
        &public,
        format!("# Ed25519 public key: build the firmware with BRDF_TRUSTED_KEYS naming this file.\n{}\n", hex(&pk))
            .as_bytes(),
    )?;
    Ok(pk)
}

/// What a signed file holds: what signing it again means.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Signed {
    /// A calibration blob (`sign`, `train --sign`).
    Calibration,
    /// An inspection recipe (`inspect teach` signs what it writes).
    Recipe,
}

/// Checks a signed calibration or recipe (`what`, named `name` in the
/// error) against the keys this build of the host tools and the firmware
/// trust; returns what was signed.
pub fn check_signed<'a>(image: &'a [u8], name: &str, what: Signed) -> anyhow::Result<&'a [u8]> {
    signed::verify(image, signed::TRUSTED_KEYS).map_err(|e| {
        let hint = match (e, what) {
            (SignatureFault::UnknownKey, _) => {
                " (its key is not among the keys the firmware was built with, BRDF_TRUSTED_KEYS)"
            }
            (SignatureFault::Unsigned, Signed::Calibration) => signed::SIGN_CALIBRATION_HINT,
            (SignatureFault::Unsigned, Signed::Recipe) => {
                " (a recipe is signed when it is taught: teach it again with `host-tools inspect teach`)"
            }
            _ => "",
        };
        anyhow::anyhow!("{name} is refused: {e}{hint}")
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keygen_writes_a_pair_that_signs_and_verifies_and_never_overwrites() {
        let dir = tempfile::tempdir().unwrap();
        let key = dir.path().join("factory.key");
        let pk = keygen(&key, false).unwrap();
        assert_eq!(read_public(&public_path(&key)).unwrap(), vec![pk]);
        let seed = read_secret(&key).unwrap();
        assert_eq!(signed::public_key(&seed), pk);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            assert_eq!(std::fs::metadata(&key).unwrap().permissions().mode() & 0o777, 0o600);
        }
        let blob = brdf_meter::test_blobs::test_blob(5, 3, 1, 4, 1.0);
        let image = sign_blob(&blob, &seed);
        assert_eq!(signed::verify(&image, &[pk]), Ok(&blob[..]));
        let e = keygen(&key, false).unwrap_err().to_string();
        assert!(e.contains("refusing to overwrite"), "{e}");
        assert_eq!(read_secret(&key).unwrap(), seed, "the refused keygen left the key alone");
        let pk2 = keygen(&key, true).unwrap();
        assert_ne!(pk2, pk);
    }

    #[test]
    fn the_checked_in_development_key_files_agree() {
        let seed = read_secret(&dev_key_path()).unwrap();
        assert_eq!(seed, DEV_SECRET);
        assert_eq!(read_public(&public_path(&dev_key_path())).unwrap(), vec![signed::public_key(&seed)]);
        for p in [dev_key_path(), public_path(&dev_key_path())] {
            let text = std::fs::read_to_string(&p).unwrap();
            assert!(text.contains("DEVELOPMENT KEY - NOT FOR PRODUCTION"), "{} must say what it is", p.display());
        }
    }

    #[test]
    fn bad_key_files_and_unsigned_or_foreign_blobs_are_named_errors() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.key");
        std::fs::write(&p, "# comment\nnot-hex\n").unwrap();
        let e = read_secret(&p).unwrap_err().to_string();
        assert!(e.contains("bad.key:2") && e.contains("64 hex digits"), "{e}");
        std::fs::write(&p, "# only a comment\n").unwrap();
        assert!(read_secret(&p).unwrap_err().to_string().contains("holds no key"));
        let blob = brdf_meter::test_blobs::test_blob(5, 3, 1, 4, 1.0);
        let e = check_signed(&blob, "cal.blob", Signed::Calibration).unwrap_err().to_string();
        assert!(e.contains("cal.blob") && e.contains("not signed") && e.contains("host-tools sign"), "{e}");
        let e = check_signed(&blob, "r.bin", Signed::Recipe).unwrap_err().to_string();
        assert!(e.contains("r.bin") && e.contains("not signed") && e.contains("inspect teach"), "{e}");
        assert!(!e.contains("calibration"), "a recipe's refusal does not speak of a calibration: {e}");
        let e = check_signed(&sign_blob(&blob, &[3; 32]), "cal.blob", Signed::Calibration).unwrap_err().to_string();
        assert!(e.contains("does not trust") && e.contains("BRDF_TRUSTED_KEYS"), "{e}");
        assert_eq!(check_signed(&sign_with_dev_key(&blob), "cal.blob", Signed::Calibration).unwrap(), &blob[..]);
    }
}
