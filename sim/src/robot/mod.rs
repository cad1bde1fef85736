//! The Thorvald-like robot: routes, the path-following controller and the smooth
//! ground-truth trajectory on the terrain.

mod controller;
mod route;
mod trajectory;
mod vibration;

pub use controller::{CONTROL_DT_S, PlanarSample, drive};
pub use route::{Leg, Route};
pub use trajectory::{GRAVITY, KNOT_DT_S, State, Trajectory, rotation};
pub use vibration::Vibration;
