//! What the decision says of a line: the kinds of defect, a defect's run
//! of pixels, the verdict a line streams and the inspection's counters.
use serde::{Deserialize, Serialize};

/// Most defects a verdict lists (further ones are counted in
/// [`verdict::MORE_DEFECTS`]).
pub const MAX_RUNS: usize = 8;

/// What kind of defect a point or a run is.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DefectKind {
    /// Gloss below its window.
    GlossLow,
    /// Gloss above its window.
    GlossHigh,
    /// Haze outside its window.
    Haze,
    /// Distinctness outside its window.
    Distinctness,
    /// Out of the reference's distribution (distance above the threshold).
    OutOfDistribution,
    /// The calibration's out-of-prior flag: unlike anything it was trained on.
    OutOfPrior,
    /// A reading was saturated, under-exposed or not finite.
    Unreadable,
}

impl DefectKind {
    /// Every kind, in wire order.
    pub const ALL: [DefectKind; 7] = [
        Self::GlossLow,
        Self::GlossHigh,
        Self::Haze,
        Self::Distinctness,
        Self::OutOfDistribution,
        Self::OutOfPrior,
        Self::Unreadable,
    ];

    /// Precedence within a run (higher wins).
    pub(super) fn rank(self) -> u8 {
        match self {
            Self::OutOfDistribution => 0,
            Self::Distinctness => 1,
            Self::Haze => 2,
            Self::GlossHigh => 3,
            Self::GlossLow => 4,
            Self::OutOfPrior => 5,
            Self::Unreadable => 6,
        }
    }

    /// Name, as the host's outputs write it.
    pub fn name(self) -> &'static str {
        match self {
            Self::GlossLow => "gloss-low",
            Self::GlossHigh => "gloss-high",
            Self::Haze => "haze",
            Self::Distinctness => "distinctness",
            Self::OutOfDistribution => "out-of-distribution",
            Self::OutOfPrior => "out-of-prior",
            Self::Unreadable => "unreadable",
        }
    }
}

/// One defect: a run of defective pixels of a line.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DefectRun {
    /// First pixel.
    pub first: u16,
    /// Pixels.
    pub len: u16,
    /// Kind.
    pub kind: DefectKind,
    /// Largest `d2` in the run.
    pub peak_d2: f32,
}

/// Bits of [`Verdict::flags`].
pub mod verdict {
    /// The line is rejected (it has a defect).
    pub const REJECT: u8 = 1 << 0;
    /// The drift alarm is on.
    pub const DRIFT_ALARM: u8 = 1 << 1;
    /// More defects than [`super::MAX_RUNS`]: only the first are listed.
    pub const MORE_DEFECTS: u8 = 1 << 2;
    /// The line's points follow (a defect line, when the host asked).
    pub const POINTS_FOLLOW: u8 = 1 << 3;
}

/// A line's defects: at most [`MAX_RUNS`], on the wire as a sequence of
/// as many as there are (a `Copy` type, so the reply enum stays `Copy`).
#[derive(Clone, Copy, Debug)]
pub struct Runs {
    len: u8,
    items: [DefectRun; MAX_RUNS],
}

const NO_RUN: DefectRun = DefectRun { first: 0, len: 0, kind: DefectKind::OutOfDistribution, peak_d2: 0.0 };

impl Runs {
    /// None.
    pub const fn new() -> Self {
        Self { len: 0, items: [NO_RUN; MAX_RUNS] }
    }
    /// Appends a defect; gives it back when full.
    pub fn push(&mut self, run: DefectRun) -> Result<(), DefectRun> {
        let slot = self.items.get_mut(self.len as usize).ok_or(run)?;
        *slot = run;
        self.len += 1;
        Ok(())
    }
    /// The defects.
    pub fn as_slice(&self) -> &[DefectRun] {
        &self.items[..self.len as usize]
    }
    /// How many.
    pub fn len(&self) -> usize {
        self.len as usize
    }
    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

impl Default for Runs {
    fn default() -> Self {
        Self::new()
    }
}

impl PartialEq for Runs {
    fn eq(&self, other: &Self) -> bool {
        self.as_slice() == other.as_slice()
    }
}

impl core::ops::Index<usize> for Runs {
    type Output = DefectRun;
    fn index(&self, i: usize) -> &DefectRun {
        &self.as_slice()[i]
    }
}

impl Serialize for Runs {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(self.as_slice())
    }
}

impl<'de> Deserialize<'de> for Runs {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = Runs;
            fn expecting(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
                write!(f, "at most {MAX_RUNS} defects")
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<Runs, A::Error> {
                let mut runs = Runs::new();
                while let Some(r) = seq.next_element::<DefectRun>()? {
                    runs.push(r).map_err(|_| serde::de::Error::invalid_length(MAX_RUNS + 1, &self))?;
                }
                Ok(runs)
            }
        }
        d.deserialize_seq(V)
    }
}

/// One line's verdict: what an inspection streams per line.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq)]
pub struct Verdict {
    /// Line number within the inspection.
    pub line: u32,
    /// [`verdict`] bits.
    pub flags: u8,
    /// The line's weighted mean gloss change over its pixels not out, GU
    /// (NaN when none has a reading): what the drift EWMA and the host's
    /// SPC figures take.
    pub mean_gloss: f32,
    /// The drift EWMA after this line, GU.
    pub ewma: f32,
    /// The line's largest point distance `d2`.
    pub max_d2: f32,
    /// Its defects, in pixel order.
    pub runs: Runs,
}

impl Verdict {
    /// Whether the line is rejected.
    pub fn rejected(&self) -> bool {
        self.flags & verdict::REJECT != 0
    }

    /// Whether the line is in a drift alarm.
    pub fn drift_alarm(&self) -> bool {
        self.flags & verdict::DRIFT_ALARM != 0
    }
}

/// The inspection's counters since it started.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct InspectCounters {
    /// Lines decided.
    pub lines: u32,
    /// Lines rejected.
    pub rejected: u32,
    /// Defects (runs) found.
    pub defects: u32,
    /// Times the drift alarm came on.
    pub drift_alarms: u32,
    /// Reject pulses driven.
    pub pulses: u32,
}
