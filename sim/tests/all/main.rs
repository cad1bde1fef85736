//! The simulator's tests, one module per subject, in one test binary (one link).

mod camera;
mod camera_features;
mod embree;
mod kernels;
mod lidar_footprint;
mod mount_error;
mod paper_world;
mod sim;
mod vibration;

use nalgebra::{Point3, Vector3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// A ray from a uniformly random point of the box `lo`..`hi` raised by 3 m, in a uniformly
/// random direction.
fn random_ray(
    rng: &mut ChaCha8Rng,
    lo: &Point3<f32>,
    hi: &Point3<f32>,
) -> (Point3<f32>, Vector3<f32>) {
    let o = Point3::new(
        rng.random_range(lo.x..hi.x),
        rng.random_range(lo.y..hi.y),
        rng.random_range(lo.z..hi.z + 3.0),
    );
    let d = loop {
        let v: Vector3<f32> = Vector3::from_fn(|_, _| StandardNormal.sample(rng));
        if let Some(u) = v.try_normalize(1e-3) {
            break u;
        }
    };
    (o, d)
}
