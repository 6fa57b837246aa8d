//! Why a match failed. A failed match never yields a pose: the caller falls
//! back to its prior (odometry or constant velocity).

/// Why a scan could not be registered.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum IcpError {
    /// The scan has no points at all.
    #[error("the scan is empty")]
    EmptyScan,
    /// The scan has points, but none is usable (all invalid, non-finite or out of range).
    #[error(
        "the scan has no valid points ({total} given, all invalid, non-finite or out of range)"
    )]
    NoValidPoints {
        /// Points given.
        total: usize,
    },
    /// Too few usable points in the scan to constrain a pose.
    #[error("the scan has only {have} usable points, at least {need} are needed")]
    TooFewScanPoints {
        /// Usable points.
        have: usize,
        /// The `icp.min_pairs` setting.
        need: usize,
    },
    /// Too few usable points in the reference.
    #[error("the reference has only {have} usable points, at least {need} are needed")]
    TooFewReferencePoints {
        /// Usable reference points.
        have: usize,
        /// The `icp.min_pairs` setting.
        need: usize,
    },
    /// The initial guess is not a finite pose.
    #[error("the initial guess is not a finite pose")]
    BadInitialGuess,
    /// Too few correspondences survived the gate and trimming.
    #[error("only {pairs} correspondences passed the gate at iteration {iteration}, at least {need} are needed")]
    TooFewPairs {
        /// Pairs left.
        pairs: usize,
        /// The `icp.min_pairs` setting.
        need: usize,
        /// Iteration at which it happened (0-based).
        iteration: u32,
    },
    /// A correlative search found no place within its window where the
    /// scan fits well enough to match from.
    #[error("no place within the search window fits the scan well enough to match from")]
    NotFound,
    /// The solver produced a non-finite pose (numerically singular problem).
    #[error("the solver found no usable solution at iteration {iteration} (non-finite pose, or fewer than 3 pairs with a surface normal)")]
    Diverged {
        /// Iteration at which it happened (0-based).
        iteration: u32,
    },
}
