//! Simulation: worlds, ray casting, robot kinematics, device emulators on
//! ptys, and replay of recorded logs.
pub mod base_emu;
pub mod carmen;
pub mod closed_loop;
pub mod coverage_metrics;
pub mod coverage_svg;
pub mod eval;
pub mod floorplan;
pub mod kinematics;
pub mod lockstep;
pub mod noise;
pub mod ros_map;
pub mod sim_report;
pub mod urg_emu;
pub mod walker;
pub mod world;
