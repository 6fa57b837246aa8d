//! Every fixed capacity of the hot path in one place (smoltcp style), so a
//! reader can see the memory bound of the scan path at a glance: the
//! algorithms' (`sweepline-core`) and the SCIP codec's (`sweepline-wire`).

pub use sweepline_core::capacity::MAX_BEAMS;
pub use sweepline_wire::scip::capacity::{
    SCIP_MAX_LINE, SCIP_MAX_REPLY_BODY, SCIP_MAX_REPLY_LINES, SCIP_MAX_SCAN_CHARS,
};

// A scan the codec accepts fits the scan the algorithms take.
const _: () = assert!(MAX_BEAMS == sweepline_wire::scip::capacity::MAX_BEAMS);
