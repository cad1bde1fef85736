//! vinebench's simulator: a procedural vineyard (terrain, trellis, vines by growth stage), a
//! Thorvald-like robot driving the paper's routes, and its sensors (IMU, wheel odometry,
//! VLP-16 lidar, 2D lidars, ground truth) as one deterministic, time-ordered stream.
//!
//! ```no_run
//! use sim::{SensorSet, SimConfig, Simulation};
//! let sim = Simulation::new(&SimConfig::default(), "s1", 42).unwrap();
//! for message in sim.stream(SensorSet::ALL) {
//!     println!("{} at {} ns", message.sensor(), message.stamp_ns());
//! }
//! ```

pub mod camera;
pub mod config;
mod error;
pub mod raycast;
pub mod rng;
pub mod robot;
pub mod sensors;
mod simulation;
pub mod world;

pub use config::SimConfig;
pub use error::SimError;
pub use simulation::{SensorSet, Simulation, Stream, Surface};

/// The default configuration file, embedded: `configs/world.toml`.
pub const DEFAULT_CONFIG_TOML: &str = include_str!("../../configs/world.toml");
