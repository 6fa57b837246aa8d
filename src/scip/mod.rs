//! SCIP 2.0 codec (sans-IO): byte framing, checksums, character decoding,
//! typed commands and replies for the Hokuyo URG family. No ports, threads,
//! clocks or allocation on the scan path; never panics on any input.
