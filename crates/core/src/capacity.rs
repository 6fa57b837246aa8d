//! Every fixed capacity of the algorithms' hot path in one place (smoltcp
//! style), so a reader can see the memory bound of the scan path at a glance.

/// Most beams a scan may carry: a UTM-30LX has 1081 steps, a URG-04LX 682 (769 in
/// all), the CARMEN logs 180 or 361. The SCIP codec's own bound
/// (`sweepline_wire::scip::capacity::MAX_BEAMS`) is the same; sweepline checks
/// the two agree when it is built.
pub const MAX_BEAMS: usize = 1440;
