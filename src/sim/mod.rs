//! Simulation: worlds, ray casting, robot kinematics, device emulators on
//! ptys, and replay of recorded logs.
pub mod base_emu;
pub mod carmen;
pub mod kinematics;
pub mod urg_emu;
pub mod world;
