//! Localisation in a saved lidar map ([`KeyframeMap`]) for systems whose originals have no
//! such mode (LIO-SAM, issue 46): the system's own front end keeps running as odometry, and
//! each sweep is registered to the saved map, after a global search when the place is not
//! known.
//!
//! The method follows two published pieces and says where it composes them:
//! - the global search is Scan Context (Kim & Kim, IROS 2018; [`crate::place::scan_context`]):
//!   the sweep's descriptor against every keyframe's, the best match's heading as the guess;
//! - the verification and the tracking are LIO-SAM's loop-closure check (Shan et al. 2020,
//!   §III-E): ICP of the sweep to a submap of keyframes around the guess, accepted when the
//!   fitness (mean squared nearest-neighbour distance) is under LIO-SAM's
//!   `historyKeyframeFitnessScore`, 0.3 m², the submap its `historyKeyframeSearchNum`, 25
//!   keyframes, downsampled at its `mappingSurfLeafSize`, 0.4 m;
//! - composed as scan-to-map localisation usually is (e.g. HDL localization's or the ROS
//!   `lio_sam` localisation forks'): `map_from_odom` corrects the odometry; a registration
//!   refused (fitness over the threshold, or a correction over 1 m or 10° from the
//!   prediction) keeps the last correction; `lost_after` refusals in a row and the system
//!   searches again. A pose is *localised* while the last `lost_after` sweeps include an
//!   accepted registration;
//! - a GNSS prior (issue 47), where the map was made with GNSS and saved its georeference:
//!   the latest fix, carried into the map, limits the global search to the keyframes within
//!   three standard deviations of it (the fix's own σ and the georeference's, combined), as
//!   a position prior gates place recognition (e.g. RTAB-Map's `Rtabmap/LoopGPS`, which
//!   drops loop candidates farther from the GPS position than a radius). No keyframe within
//!   it and the search finds nothing.

use nalgebra::{Isometry3, Matrix3, Point3, UnitQuaternion, Vector3};

use super::keyframes::KeyframeMap;
use crate::place::scan_context::{ScanContext, ScanContextConfig, ScanContextDatabase};
use crate::registration::icp::{IcpConfig, IcpTarget, icp};
use crate::registration::voxel::downsample;

/// The localiser's parameters (the module documentation gives their sources).
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LocalizerConfig {
    pub scan_context: ScanContextConfig,
    /// Keyframes nearest the guess that make the submap.
    pub submap_keyframes: usize,
    /// The submap's voxel leaf, metres.
    pub leaf_m: f64,
    /// The largest accepted ICP fitness, m².
    pub max_fitness: f64,
    /// The largest correction of the prediction accepted while tracking.
    pub max_correction_m: f64,
    pub max_correction_rad: f64,
    /// Refused registrations in a row after which the place is searched for again.
    pub lost_after: usize,
    /// The standard deviation of a map's georeference, m, combined with a fix's own in a
    /// GNSS prior: the alignment's heading error turns the map about its origin (1° over a
    /// 60 m block is 1 m).
    pub gnss_georeference_sigma_m: f64,
}

impl Default for LocalizerConfig {
    fn default() -> Self {
        Self {
            scan_context: ScanContextConfig::default(),
            submap_keyframes: 25,
            leaf_m: 0.4,
            max_fitness: 0.3,
            max_correction_m: 1.0,
            max_correction_rad: 10f64.to_radians(),
            lost_after: 10,
            gnss_georeference_sigma_m: 1.0,
        }
    }
}

/// What one sweep gave.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Localized {
    /// The sensor's pose in the map.
    pub map_from_sensor: Isometry3<f64>,
    /// Whether a recent registration to the map was accepted.
    pub localized: bool,
}

/// Localisation in a [`KeyframeMap`].
#[derive(Debug)]
pub struct MapLocalizer {
    cfg: LocalizerConfig,
    map: KeyframeMap,
    contexts: ScanContextDatabase,
    /// `map_from_odom`, once known (an initial guess, or a first accepted registration).
    map_from_odom: Option<Isometry3<f64>>,
    /// Sweeps since the last accepted registration (`None`: never accepted).
    since_accepted: Option<usize>,
    /// The submap last built: its keyframes and ICP target.
    submap: Option<(Vec<usize>, IcpTarget)>,
    /// The latest GNSS prior: the sensor's horizontal position in the map and the radius
    /// the global search keeps, m.
    gnss_prior: Option<(Vector3<f64>, f64)>,
    /// Global searches made and accepted, for the plugin's summary.
    pub searches: usize,
    pub relocalizations: usize,
}

impl MapLocalizer {
    pub fn new(map: KeyframeMap, cfg: LocalizerConfig) -> Self {
        let mut contexts = ScanContextDatabase::new(cfg.scan_context.clone());
        for k in &map.keyframes {
            contexts.add(ScanContext::new(&k.points, &cfg.scan_context));
        }
        Self {
            cfg,
            map,
            contexts,
            map_from_odom: None,
            since_accepted: None,
            submap: None,
            gnss_prior: None,
            searches: 0,
            relocalizations: 0,
        }
    }

    /// Starts from a guess of the sensor's pose in the map at odometry `odom_from_sensor`.
    pub fn guess(&mut self, map_from_sensor: &Isometry3<f64>, odom_from_sensor: &Isometry3<f64>) {
        self.map_from_odom = Some(map_from_sensor * odom_from_sensor.inverse());
    }

    /// A GNSS prior for the global search: the sensor's position in the map (a fix carried
    /// in by the map's georeference) and its horizontal standard deviation, m; the search
    /// keeps the keyframes within three of them.
    pub fn gnss_prior(&mut self, sensor_in_map: &Vector3<f64>, sigma_m: f64) {
        self.gnss_prior = Some((*sensor_in_map, 3.0 * sigma_m));
    }

    /// A GNSS fix as a prior for the global search, where the map is georeferenced (made
    /// with GNSS; else nothing): the antenna's position and covariance in east-north-up,
    /// carried into the map; its spread combines the fix's larger horizontal variance, the
    /// georeference's (`gnss_georeference_sigma_m`) and the antenna's horizontal offset from
    /// the sensor, m (whose direction is not known before the heading is).
    pub fn gnss_fix(
        &mut self,
        antenna_enu: &Vector3<f64>,
        covariance_enu: &Matrix3<f64>,
        antenna_offset_m: f64,
    ) {
        let Some(map_from_enu) = self.map.map_from_enu else {
            return;
        };
        let sigma = (covariance_enu[(0, 0)].max(covariance_enu[(1, 1)])
            + self.cfg.gnss_georeference_sigma_m.powi(2)
            + antenna_offset_m.powi(2))
        .sqrt();
        self.gnss_prior(&(map_from_enu * Point3::from(*antenna_enu)).coords, sigma);
    }

    pub fn keyframes(&self) -> usize {
        self.map.keyframes.len()
    }

    /// The submap of the keyframes nearest `at` (map frame), rebuilt only when they change.
    fn submap_near(&mut self, at: &Vector3<f64>) -> &mut IcpTarget {
        let mut nearest: Vec<(f64, usize)> = self
            .map
            .keyframes
            .iter()
            .enumerate()
            .map(|(i, k)| {
                (
                    (k.map_from_sensor.translation.vector - at).norm_squared(),
                    i,
                )
            })
            .collect();
        nearest.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut chosen: Vec<usize> = nearest
            .iter()
            .take(self.cfg.submap_keyframes.max(1))
            .map(|&(_, i)| i)
            .collect();
        chosen.sort_unstable();
        if self.submap.as_ref().is_none_or(|(ids, _)| *ids != chosen) {
            let mut points = Vec::new();
            for &i in &chosen {
                let k = &self.map.keyframes[i];
                points.extend(k.points.iter().map(|p| {
                    (k.map_from_sensor
                        * Point3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])))
                    .coords
                }));
            }
            let target = IcpTarget::new(downsample(&points, self.cfg.leaf_m), 5, 0.1);
            self.submap = Some((chosen, target));
        }
        &mut self.submap.as_mut().expect("just built").1
    }

    /// ICP of `source` (sensor frame) to the submap around `guess`; the result if accepted.
    fn register(
        &mut self,
        source: &[Vector3<f64>],
        guess: &Isometry3<f64>,
    ) -> Option<Isometry3<f64>> {
        let max_fitness = self.cfg.max_fitness;
        let target = self.submap_near(&guess.translation.vector);
        let result = icp(source, target, guess, &IcpConfig::default())?;
        (result.converged && result.fitness <= max_fitness).then_some(result.target_from_source)
    }

    /// One sweep: its points in the sensor frame and the odometry's `odom_from_sensor`.
    pub fn update(&mut self, odom_from_sensor: &Isometry3<f64>, points: &[[f32; 3]]) -> Localized {
        let source: Vec<Vector3<f64>> = points
            .iter()
            .map(|p| Vector3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])))
            .collect();
        let lost = self.since_accepted.is_none_or(|n| n >= self.cfg.lost_after);
        let accepted = match self.map_from_odom {
            // Tracking (or starting from a guess): register at the prediction.
            Some(map_from_odom) if !lost || self.since_accepted.is_none() => {
                let predicted = map_from_odom * odom_from_sensor;
                self.register(&source, &predicted).filter(|r| {
                    let d = predicted.inverse() * r;
                    d.translation.vector.norm() <= self.cfg.max_correction_m
                        && d.rotation.angle() <= self.cfg.max_correction_rad
                })
            }
            _ => None,
        };
        let accepted = match accepted {
            Some(r) => Some(r),
            None if lost => self.search(&source, points),
            None => None,
        };
        match accepted {
            Some(map_from_sensor) => {
                self.map_from_odom = Some(map_from_sensor * odom_from_sensor.inverse());
                self.since_accepted = Some(0);
            }
            None => {
                self.since_accepted = self.since_accepted.map(|n| n + 1);
            }
        }
        let map_from_odom = self.map_from_odom.unwrap_or_else(Isometry3::identity);
        Localized {
            map_from_sensor: map_from_odom * odom_from_sensor,
            localized: self.since_accepted.is_some_and(|n| n < self.cfg.lost_after),
        }
    }

    /// The global search: Scan Context's best keyframe, verified by ICP at its heading.
    fn search(&mut self, source: &[Vector3<f64>], points: &[[f32; 3]]) -> Option<Isometry3<f64>> {
        self.searches += 1;
        let query = ScanContext::new(points, &self.cfg.scan_context);
        let m = match self.gnss_prior {
            Some((at, radius)) => {
                let keyframes = &self.map.keyframes;
                self.contexts.search_among(&query, |i| {
                    (keyframes[i].map_from_sensor.translation.vector - at)
                        .xy()
                        .norm()
                        <= radius
                })?
            }
            None => self.contexts.search(&query, 0)?,
        };
        let keyframe = self.map.keyframes[m.index].map_from_sensor;
        let guess = keyframe * UnitQuaternion::from_euler_angles(0.0, 0.0, m.yaw_rad);
        let found = self.register(source, &guess)?;
        self.relocalizations += 1;
        Some(found)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::maps::keyframes::MapKeyframe;

    /// A corridor of posts: walls of points at y = ±3 m with posts every 2 m along x from 0
    /// to 60 m, seen from a sensor at `x` (heading +x) out to 20 m: every place differs in
    /// what is in range at its ends, near the corridor's ends.
    fn scan(x: f64) -> Vec<[f32; 3]> {
        let mut points = Vec::new();
        for k in 0..=30 {
            let px = 2.0 * k as f64;
            for side in [-3.0, 3.0] {
                for dz in 0..8 {
                    let z = -0.5 + 0.2 * f64::from(dz);
                    for dx in 0..4 {
                        let p = [px + 0.05 * f64::from(dx) - x, side, z];
                        if p[0].hypot(p[1]) < 20.0 {
                            points.push([p[0] as f32, p[1] as f32, p[2] as f32]);
                        }
                    }
                }
            }
        }
        // The end wall at x = 60, so that places are told apart by it.
        for y in -30..=30 {
            for dz in 0..8 {
                let p = [60.0 - x, 0.1 * f64::from(y), -0.5 + 0.2 * f64::from(dz)];
                if p[0].hypot(p[1]) < 20.0 {
                    points.push([p[0] as f32, p[1] as f32, p[2] as f32]);
                }
            }
        }
        points
    }

    fn corridor_map() -> KeyframeMap {
        KeyframeMap {
            map_from_enu: None,
            keyframes: (0..=55)
                .map(|i| MapKeyframe {
                    map_from_sensor: Isometry3::translation(f64::from(i), 0.0, 0.0),
                    points: scan(f64::from(i)),
                })
                .collect(),
        }
    }

    /// Started with no guess and odometry in a frame of its own, it finds its place in the
    /// map and then tracks it within centimetres.
    #[test]
    fn it_finds_its_place_and_tracks_it() {
        let mut localizer = MapLocalizer::new(corridor_map(), LocalizerConfig::default());
        // Odometry starts at its own origin; the robot truly starts at x = 50.3.
        let mut last = None;
        for step in 0..20 {
            let x = 50.3 + 0.2 * f64::from(step);
            let odom = Isometry3::translation(x - 50.3, 0.0, 0.0);
            last = Some((x, localizer.update(&odom, &scan(x))));
        }
        let (x, l) = last.expect("steps");
        assert!(l.localized, "{l:?}");
        let error = (l.map_from_sensor.translation.vector - Vector3::new(x, 0.0, 0.0)).norm();
        assert!(error < 0.05, "{error} m off at x = {x}");
        assert!(localizer.relocalizations >= 1);
    }

    /// A GNSS prior limits the global search to the keyframes around the fix: at the true
    /// place it localises as without one; 40 m off, it never localises at the true place;
    /// off the map, it searches and finds nothing.
    #[test]
    fn a_gnss_prior_limits_the_global_search() {
        let drive = |prior: Option<(f64, f64)>| {
            let mut localizer = MapLocalizer::new(corridor_map(), LocalizerConfig::default());
            let mut out = Vec::new();
            for step in 0..20 {
                let x = 50.3 + 0.2 * f64::from(step);
                if let Some((px, sigma)) = prior {
                    localizer
                        .gnss_prior(&Vector3::new(px + 0.2 * f64::from(step), 0.0, 0.0), sigma);
                }
                let odom = Isometry3::translation(x - 50.3, 0.0, 0.0);
                out.push((x, localizer.update(&odom, &scan(x))));
            }
            (out, localizer.searches, localizer.relocalizations)
        };
        let (at_truth, _, found) = drive(Some((50.3, 0.5)));
        let (x, l) = at_truth.last().copied().expect("steps");
        assert!(l.localized && found >= 1, "{l:?}");
        assert!((l.map_from_sensor.translation.vector - Vector3::new(x, 0.0, 0.0)).norm() < 0.05);

        let (elsewhere, ..) = drive(Some((10.3, 1.0)));
        for (x, l) in &elsewhere {
            assert!(
                !l.localized || (l.map_from_sensor.translation.x - x).abs() > 3.0,
                "localised at the true place {x} against a prior 40 m away: {l:?}"
            );
        }

        let (off_map, searches, found) = drive(Some((200.0, 1.0)));
        assert!(off_map.iter().all(|(_, l)| !l.localized));
        assert!(
            searches >= 1 && found == 0,
            "{searches} searches, {found} found"
        );

        // Through a georeferenced map: fixes in east-north-up, 100 m east of the map's
        // frame, carried in by the map's `map_from_enu`; without a georeference, no prior.
        let mut map = corridor_map();
        map.map_from_enu = Some(Isometry3::translation(-100.0, 0.0, 0.0));
        let mut localizer = MapLocalizer::new(map, LocalizerConfig::default());
        let tight = Matrix3::from_diagonal_element(1e-4);
        localizer.gnss_fix(&Vector3::new(300.0, 0.0, 0.0), &tight, 0.1);
        let l = localizer.update(&Isometry3::identity(), &scan(50.3));
        assert!(
            !l.localized,
            "a fix 150 m past the corridor's end, yet localised: {l:?}"
        );
        localizer.gnss_fix(&Vector3::new(150.3, 0.0, 0.0), &tight, 0.1);
        let mut l = l;
        for _ in 0..=LocalizerConfig::default().lost_after {
            l = localizer.update(&Isometry3::identity(), &scan(50.3));
        }
        assert!(l.localized, "{l:?}");
        assert!(
            (l.map_from_sensor.translation.x - 50.3).abs() < 0.05,
            "{l:?}"
        );
        let mut plain = MapLocalizer::new(corridor_map(), LocalizerConfig::default());
        plain.gnss_fix(&Vector3::new(300.0, 0.0, 0.0), &tight, 0.1);
        assert!(plain.gnss_prior.is_none());
    }
}
