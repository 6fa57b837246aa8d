//! Every fixed capacity of the hot path in one place (smoltcp style), so a
//! reader can see the memory bound of the scan path at a glance.

/// Most beams a scan may carry: a UTM-30LX has 1081 steps, a URG-04LX 682 (769 in
/// all), the CARMEN logs 180 or 361.
pub const MAX_BEAMS: usize = 1440;

/// Longest SCIP line payload we accept before declaring a desync: 64 data bytes
/// plus checksum, with room for long VV/II text lines of newer firmware.
pub const SCIP_MAX_LINE: usize = 160;

/// Largest SCIP scan payload in characters (1440 beams × 6 chars for distance+intensity).
pub const SCIP_MAX_SCAN_CHARS: usize = MAX_BEAMS * 6;
