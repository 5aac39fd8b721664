//! On-device inspection: the instrument over a production line decides, line
//! by line, whether the surface is the taught reference ("golden sample").
//!
//! - [`recipe`]: the inspection recipe (per pixel the reference statistics,
//!   the tolerances, hysteresis, minimum defect size, drift and reject
//!   settings): one binary layout, written by `host-tools inspect teach`,
//!   read in place on the device, signed like a calibration.
//! - [`decide`]: the decision on each point's corrected readings (distance
//!   to the reference, the gloss readings' change) and on each line
//!   (defects, verdict, drift EWMA, counters); the host runs the same code.
//! - [`reject`]: when the reject output fires (delay in time or in lines).
//!
//! The recipes are stored A/B like the calibrations ([`RecipeStore`], the
//! same [`crate::store::SlotStore`] on the recipe slots); a recipe names the
//! calibration it was taught with (the blob's CRC) and is refused for
//! another.
pub mod decide;
pub mod recipe;
pub mod reject;

use crate::protocol::DeviceError;
use crate::store::{SlotContent, SlotStore};
pub use decide::{DefectKind, DefectRun, InspectCounters, Inspector, Verdict};
pub use recipe::{RecipeFault, RecipeView};

/// The recipes, as a store's content.
pub struct Recipes;

impl SlotContent for Recipes {
    type View = RecipeView<'static>;

    fn parse(bytes: &'static [u8]) -> Result<Self::View, DeviceError> {
        RecipeView::parse(bytes).map_err(DeviceError::RecipeRejected)
    }

    fn unreadable(bytes: &'static [u8]) -> Option<DeviceError> {
        matches!(RecipeView::parse(bytes), Err(RecipeFault::UnsupportedVersion))
            .then_some(DeviceError::RecipeRejected(RecipeFault::UnsupportedVersion))
    }
}

/// The two-slot recipe store.
pub type RecipeStore<F> = SlotStore<F, Recipes>;

/// Whether `recipe` fits a device of P pixels and M readings whose active
/// calibration has CRC `calibration_crc` (`None`: no calibration).
pub fn check_recipe<const M: usize, const P: usize>(
    recipe: &RecipeView<'_>,
    calibration_crc: Option<u32>,
) -> Result<(), DeviceError> {
    if recipe.pixels() != P || recipe.leds() != M {
        return Err(DeviceError::RecipeRejected(RecipeFault::WrongShape));
    }
    let taught = recipe.settings().calibration_crc;
    match calibration_crc {
        Some(active) if active == taught => Ok(()),
        active => Err(DeviceError::RecipeForOtherCalibration { recipe: taught, active: active.unwrap_or(0) }),
    }
}
