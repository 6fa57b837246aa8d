//! Criterion benchmarks of sweepline's hot paths: see `benches/`.
