//! Simulation: worlds, ray casting, robot kinematics, device emulators on
//! ptys, and replay of recorded logs.
pub mod world;
pub mod urg_emu;

pub mod carmen;
