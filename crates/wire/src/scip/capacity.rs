//! Every fixed capacity of the SCIP codec in one place (smoltcp style), so
//! a reader can see the memory bound of the scan path at a glance.

/// Most beams a scan may carry: a UTM-30LX has 1081 steps, a URG-04LX 682 (769 in
/// all), the CARMEN logs 180 or 361.
pub const MAX_BEAMS: usize = 1440;

/// Longest SCIP line payload we accept before declaring a desync: 64 data bytes
/// plus checksum, with room for long VV/II text lines of newer firmware.
pub const SCIP_MAX_LINE: usize = 160;

/// Largest SCIP scan payload in characters (1440 beams × 6 chars for distance+intensity).
pub const SCIP_MAX_SCAN_CHARS: usize = MAX_BEAMS * 6;

/// Most data lines one SCIP reply may carry: a full-width scan with
/// intensities (8640 characters in 64-character lines) plus its timestamp line.
pub const SCIP_MAX_REPLY_LINES: usize = SCIP_MAX_SCAN_CHARS / 64 + 8;

/// Bytes of payload (checksums removed) one SCIP reply may carry: the largest
/// scan plus its 4-character timestamp, with one spare line.
pub const SCIP_MAX_REPLY_BODY: usize = SCIP_MAX_SCAN_CHARS + 4 + 64;
