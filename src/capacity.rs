//! Every fixed capacity of the hot path in one place (smoltcp style), so a
//! reader can see the memory bound of the scan path at a glance.

/// Most beams a scan may carry: a UTM-30LX has 1081 steps, a URG-04LX 682 (769 in
/// all), the CARMEN logs 180 or 361.
pub use sweepline_wire::scip::capacity::MAX_BEAMS;

/// The SCIP codec's capacities (`sweepline-wire`).
pub use sweepline_wire::scip::capacity::{
    SCIP_MAX_LINE, SCIP_MAX_REPLY_BODY, SCIP_MAX_REPLY_LINES, SCIP_MAX_SCAN_CHARS,
};
