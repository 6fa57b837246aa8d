//! Simulation: worlds, ray casting, robot kinematics, device emulators on
//! ptys, and replay of recorded logs.
pub mod carmen;
pub mod world;
