//! Simulation: worlds, ray casting, robot kinematics, device emulators on
//! ptys, and replay of recorded logs.
pub mod coverage_metrics;
pub mod floorplan;
pub mod world;
