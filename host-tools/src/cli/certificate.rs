//! A standard's certificate as it is printed: its value, its uncertainty,
//! and the coverage factor that uncertainty is stated at. `standardise`
//! and `verify` take the uncertainty as the standard uncertainty (k = 1)
//! unless they are given the certificate's k; then it is the expanded
//! uncertainty U the certificate prints, and the standard uncertainty is
//! U / k (GUM 7.2.3), so nobody has to divide by hand.
use crate::device::coverage_factor::LARGE_DOF_FACTOR;
use anyhow::ensure;

/// The largest coverage factor a certificate is taken to state (Student's
/// t at 95.45 % for 2 degrees of freedom is 4.53; 10 is far beyond any).
pub const MAX_CERTIFICATE_K: f64 = 10.0;

/// What the user entered of the certificate's uncertainty: `u` and, when
/// the certificate's expanded uncertainty was entered, its coverage
/// factor `k`; `flags` names the two options for the messages.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CertificateUncertainty {
    /// As entered: the standard uncertainty, or with `k` the expanded one.
    pub u: f64,
    /// The coverage factor it was stated at, when it is an expanded one.
    pub k: Option<f64>,
    /// The options they came from, e.g. `("--tile-u", "--tile-k")`.
    pub flags: (&'static str, &'static str),
}

impl CertificateUncertainty {
    /// The certificate's standard uncertainty (k = 1): `u`, or `u / k`.
    /// A `k` below 1 (an expanded uncertainty narrower than the standard
    /// one), above [`MAX_CERTIFICATE_K`] or not finite is refused, named.
    pub fn standard(&self) -> anyhow::Result<f64> {
        let Some(k) = self.k else { return Ok(self.u) };
        ensure!(
            k.is_finite() && (1.0..=MAX_CERTIFICATE_K).contains(&k),
            "{} {k}: a certificate's coverage factor is 1 to {MAX_CERTIFICATE_K} (it is printed beside its expanded \
             uncertainty U, often k = 2); give {} the U it prints",
            self.flags.1,
            self.flags.0
        );
        Ok(self.u / k)
    }

    /// The certificate's coverage factor: the one entered, else that of
    /// many degrees of freedom (2).
    pub fn coverage_factor(&self) -> f64 {
        self.k.unwrap_or(LARGE_DOF_FACTOR)
    }

    /// `check`'s standard (a tile, a glass, a gloss standard) built on
    /// [`Self::standard`]; a refusal of a value worked out from U / k says
    /// so ("here 0.1 = --tile-u 0.2 / --tile-k 2").
    pub fn checked<T>(&self, check: impl FnOnce(f64) -> anyhow::Result<T>) -> anyhow::Result<T> {
        let u = self.standard()?;
        check(u).map_err(|e| match self.k {
            Some(k) => anyhow::anyhow!("{e}; here {u} = {} {} / {} {k}", self.flags.0, self.u, self.flags.1),
            None => e,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_expanded_uncertainty_is_divided_by_its_coverage_factor_and_a_bad_one_is_named() {
        let entered = |u, k| CertificateUncertainty { u, k, flags: ("--tile-u", "--tile-k") };
        assert_eq!(entered(0.004, None).standard().unwrap(), 0.004);
        assert_eq!(entered(0.004, Some(2.0)).standard().unwrap(), 0.002);
        assert_eq!((entered(0.004, None).coverage_factor(), entered(0.004, Some(2.5)).coverage_factor()), (2.0, 2.5));
        // The expanded uncertainty E_n takes, k u: the U printed with its
        // k, twice the standard uncertainty without.
        let expanded = |c: CertificateUncertainty| c.coverage_factor() * c.standard().unwrap();
        assert_eq!((expanded(entered(0.004, None)), expanded(entered(0.004, Some(2.5)))), (0.008, 0.004));
        for bad in [0.5, 11.0, f64::NAN, f64::INFINITY] {
            let e = entered(0.004, Some(bad)).standard().unwrap_err().to_string();
            assert!(e.starts_with("--tile-k ") && e.contains("give --tile-u the U it prints"), "{e}");
        }
        // A refusal of a value worked out from U / k says so; of one
        // entered, it is the check's own.
        let refuse = |u: f64| -> anyhow::Result<()> { anyhow::bail!("{u} refused") };
        assert_eq!(
            entered(0.004, Some(2.0)).checked(refuse).unwrap_err().to_string(),
            "0.002 refused; here 0.002 = --tile-u 0.004 / --tile-k 2"
        );
        assert_eq!(entered(0.004, None).checked(refuse).unwrap_err().to_string(), "0.004 refused");
        assert_eq!(entered(0.004, Some(2.0)).checked(Ok).unwrap(), 0.002);
    }
}
