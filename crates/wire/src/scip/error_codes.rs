//! Range values below DMIN are error codes, not ranges; their meaning depends
//! on the model. The URG-04LX family (URG/UBG/UHG) uses the 0–19 table below;
//! other models are reported as unclassified codes rather than guessed.

/// Which error-code table a sensor uses, decided from its `MODL` string.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ModelFamily {
    /// URG-04LX, URG-04LX-UG01, UBG-04LX-F01, UHG-08LX: the 0–19 table; FF
    /// intensity mode; no ME/GE.
    Urg04lx,
    /// Time-of-flight models (UTM-30LX, UXM, UST): ME/GE intensity; their own table.
    TimeOfFlight,
    /// Anything else.
    Unknown,
}

impl ModelFamily {
    /// The family of a `MODL` value such as `URG-04LX(Hokuyo Automatic Co.,Ltd.)`.
    pub fn from_model(model: &str) -> Self {
        let m = model.trim_start();
        if m.starts_with("URG-04LX") || m.starts_with("UBG-04LX") || m.starts_with("UHG-08LX") {
            ModelFamily::Urg04lx
        } else if m.starts_with("UTM-") || m.starts_with("UXM-") || m.starts_with("UST-") {
            ModelFamily::TimeOfFlight
        } else {
            ModelFamily::Unknown
        }
    }

    /// True when the family answers ME/GE (never send them to a URG-04LX).
    pub fn supports_me(&self) -> bool {
        matches!(self, ModelFamily::TimeOfFlight)
    }

    /// True when the family has the undocumented `FF` intensity cluster mode.
    pub fn supports_ff_intensity(&self) -> bool {
        matches!(self, ModelFamily::Urg04lx)
    }
}

/// Meaning of a URG-04LX-family error code.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ErrorKind {
    /// 0: possibly an object at 22 m (beyond range).
    PossibleObjectAt22m,
    /// 1–5: reflected light too weak.
    WeakReflection,
    /// 6: possibly an object at 5.7 m.
    PossibleObjectAt5_7m,
    /// 7: neighbouring steps have errors.
    NeighbourErrors,
    /// 8: intensity difference of the two waves.
    TwoWaveIntensityDifference,
    /// 9: same step failed in the last two scans.
    RepeatedFailure,
    /// 10–17: other errors.
    Other,
    /// 18: strong reflector.
    StrongReflector,
    /// 19: non-measurable step.
    NonMeasurable,
    /// A code of a model whose table is not known here.
    Unclassified,
}

impl ErrorKind {
    /// The meaning in words.
    pub fn meaning(&self) -> &'static str {
        match self {
            ErrorKind::PossibleObjectAt22m => "possibly an object at 22 m",
            ErrorKind::WeakReflection => "reflected light too weak",
            ErrorKind::PossibleObjectAt5_7m => "possibly an object at 5.7 m",
            ErrorKind::NeighbourErrors => "neighbouring steps have errors",
            ErrorKind::TwoWaveIntensityDifference => "intensity difference of two waves",
            ErrorKind::RepeatedFailure => "same step failed in the last two scans",
            ErrorKind::Other => "other error",
            ErrorKind::StrongReflector => "strong reflector",
            ErrorKind::NonMeasurable => "non-measurable step",
            ErrorKind::Unclassified => "error code (no table for this model)",
        }
    }

    /// True for codes that suggest nothing reflects within range (free space
    /// up to the sensor's reach), as opposed to a failed measurement.
    pub fn suggests_no_return(&self) -> bool {
        matches!(
            self,
            ErrorKind::PossibleObjectAt22m | ErrorKind::PossibleObjectAt5_7m
        )
    }
}

/// An error reading: the raw code and its meaning for the model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ErrorReading {
    /// The raw value sent by the sensor (below DMIN).
    pub code: u32,
    /// Its meaning.
    pub kind: ErrorKind,
}

impl ErrorReading {
    /// Classifies a code below DMIN for `family`.
    pub fn classify(code: u32, family: ModelFamily) -> Self {
        let kind = match family {
            ModelFamily::Urg04lx => match code {
                0 => ErrorKind::PossibleObjectAt22m,
                1..=5 => ErrorKind::WeakReflection,
                6 => ErrorKind::PossibleObjectAt5_7m,
                7 => ErrorKind::NeighbourErrors,
                8 => ErrorKind::TwoWaveIntensityDifference,
                9 => ErrorKind::RepeatedFailure,
                10..=17 => ErrorKind::Other,
                18 => ErrorKind::StrongReflector,
                19 => ErrorKind::NonMeasurable,
                _ => ErrorKind::Unclassified,
            },
            _ => ErrorKind::Unclassified,
        };
        ErrorReading { code, kind }
    }
}

/// One decoded distance value, never an error code disguised as a range.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Reading {
    /// A valid range in millimetres (DMIN ≤ value ≤ DMAX).
    Range(u32),
    /// A value below DMIN: an error code.
    Error(ErrorReading),
    /// A value above DMAX (millimetres): not trustworthy as a range.
    BeyondMax(u32),
}

impl Reading {
    /// Classifies a raw value with the sensor's DMIN/DMAX and model family.
    pub fn classify(raw: u32, dmin: u32, dmax: u32, family: ModelFamily) -> Self {
        if raw < dmin {
            Reading::Error(ErrorReading::classify(raw, family))
        } else if raw > dmax {
            Reading::BeyondMax(raw)
        } else {
            Reading::Range(raw)
        }
    }

    /// The range in millimetres when valid.
    pub fn range_mm(&self) -> Option<u32> {
        match self {
            Reading::Range(r) => Some(*r),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urg_table_covers_0_to_19() {
        let f = ModelFamily::Urg04lx;
        assert_eq!(
            ErrorReading::classify(0, f).kind,
            ErrorKind::PossibleObjectAt22m
        );
        for c in 1..=5 {
            assert_eq!(ErrorReading::classify(c, f).kind, ErrorKind::WeakReflection);
        }
        assert_eq!(
            ErrorReading::classify(6, f).kind,
            ErrorKind::PossibleObjectAt5_7m
        );
        assert_eq!(
            ErrorReading::classify(7, f).kind,
            ErrorKind::NeighbourErrors
        );
        assert_eq!(
            ErrorReading::classify(8, f).kind,
            ErrorKind::TwoWaveIntensityDifference
        );
        assert_eq!(
            ErrorReading::classify(9, f).kind,
            ErrorKind::RepeatedFailure
        );
        for c in 10..=17 {
            assert_eq!(ErrorReading::classify(c, f).kind, ErrorKind::Other);
        }
        assert_eq!(
            ErrorReading::classify(18, f).kind,
            ErrorKind::StrongReflector
        );
        assert_eq!(ErrorReading::classify(19, f).kind, ErrorKind::NonMeasurable);
        assert_eq!(
            ErrorReading::classify(2, ModelFamily::TimeOfFlight).kind,
            ErrorKind::Unclassified
        );
    }

    #[test]
    fn readings_never_pass_errors_as_ranges() {
        let f = ModelFamily::Urg04lx;
        assert!(matches!(
            Reading::classify(19, 20, 5600, f),
            Reading::Error(_)
        ));
        assert_eq!(Reading::classify(20, 20, 5600, f), Reading::Range(20));
        assert_eq!(Reading::classify(5600, 20, 5600, f), Reading::Range(5600));
        assert_eq!(
            Reading::classify(5601, 20, 5600, f),
            Reading::BeyondMax(5601)
        );
        assert_eq!(Reading::classify(3, 20, 5600, f).range_mm(), None);
    }

    #[test]
    fn families_from_model_strings() {
        assert_eq!(
            ModelFamily::from_model("URG-04LX(Hokuyo Automatic Co.,Ltd.)"),
            ModelFamily::Urg04lx
        );
        assert_eq!(
            ModelFamily::from_model("URG-04LX-UG01(Hokuyo Automatic Co.,Ltd.)"),
            ModelFamily::Urg04lx
        );
        assert_eq!(
            ModelFamily::from_model("UTM-30LX(Hokuyo Automatic Co.,Ltd.)"),
            ModelFamily::TimeOfFlight
        );
        assert_eq!(ModelFamily::from_model("XYZ"), ModelFamily::Unknown);
        assert!(!ModelFamily::Urg04lx.supports_me());
        assert!(ModelFamily::Urg04lx.supports_ff_intensity());
    }
}
