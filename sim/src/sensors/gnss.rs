//! A GNSS receiver whose fix depends on the sky its antenna sees (issue 47): the model
//! alone, a function of the antenna's position, the time and which satellites a ray from the
//! antenna reaches, so that it can be tested without the rest of the simulation.
//!
//! - **Sky.** A fixed constellation of `satellites` satellites, drawn once from the run's
//!   seed uniformly over the sphere (so about half are above the horizon, as for one GNSS
//!   constellation), each moving along a great circle of the sky at the angular rate of a
//!   GPS orbit seen from the Earth's centre (one revolution per half sidereal day,
//!   43 082 s): a few degrees over a run. Satellites below the elevation mask (10°, the
//!   usual receiver default) are not tracked; the others are visible when the caller's ray
//!   from the antenna reaches the sky (the canopy, posts, wires and fence block it).
//! - **Geometry.** With the visible satellites' unit vectors the dilutions of precision
//!   follow from the least-squares position-and-clock solution: `Q = (GᵀG)⁻¹` with rows
//!   `[-e, 1]` of `G` in east-north-up (Misra & Enge, *Global Positioning System*, 2nd ed.,
//!   §6.1), `HDOP = √(Q_ee + Q_nn)`, `VDOP = √Q_uu`.
//! - **Fix.** Fewer than 4 visible: none. `consumer`: single point with 4 or more. `rtk`:
//!   carrier-phase RTK needs `rtk_min_satellites` (5: four double differences) with a
//!   PDOP under `rtk_max_pdop`; with them the receiver is float until they have held for
//!   `rtk_fix_after_s` without a break (the ambiguities resolved: u-blox ZED-F9P's RTK
//!   convergence, < 10 s, datasheet UBX-17051259), then fixed; any break (too few
//!   satellites) starts that time again.
//! - **Error.** Each status has its own error, a first-order Gauss–Markov process per axis
//!   (Ornstein–Uhlenbeck: `x_k = φ x_{k-1} + √(1-φ²) σ w_k`, `φ = e^{-Δt/τ}`), all run
//!   every epoch so that a status entered has its stationary spread at once. Its σ are the
//!   datasheets' open-sky figures scaled by the dilution of precision where it exceeds 1
//!   (position error = DOP × range error; open-sky multi-GNSS DOPs are about 1 or less):
//!   `σ_h · max(HDOP, 1)` per horizontal axis, `σ_v · max(VDOP, 1)` vertically. The reported
//!   covariance is those variances, as a receiver reports its own accuracy estimate.
//!
//! What is not modelled yet: multipath and non-line-of-sight reception (a blocked satellite
//! is lost, never received by a reflection), the antenna's phase-centre variation, and
//! correlation between the axes.

use nalgebra::{Isometry3, Matrix4, Point3, Unit, UnitQuaternion, Vector3};
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

use super::Scene;
use crate::raycast::RayCaster;
use crate::rng::SimRng;

/// How far a ray looks for what hides a satellite, metres: well past a block's far side.
pub const SKY_REACH_M: f32 = 1000.0;

/// Whether a ray from `antenna` (world frame: x east, y north, z up) towards `direction`
/// reaches the sky: nothing the caster holds lies on it. The world's mesh is its canopy,
/// trunks, posts, wires, fence and ground, so each of them can hide a satellite.
pub fn sky_visible(
    caster: &dyn RayCaster,
    antenna: &Vector3<f64>,
    direction: &Vector3<f64>,
) -> bool {
    let origin = Point3::from(antenna.cast::<f32>());
    let dir = direction.normalize().cast::<f32>();
    caster.cast(&origin, &dir, 1e-3, SKY_REACH_M).is_none()
}

/// Half a sidereal day, seconds: a GPS satellite's orbital period.
pub const GPS_ORBIT_S: f64 = 43_082.0;

/// What the receiver is.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum GnssProfile {
    /// No receiver.
    #[default]
    None,
    /// A consumer receiver: single-point fixes of metres.
    Consumer,
    /// A multi-band RTK receiver with corrections: fixed, float or single.
    Rtk,
}

/// The fix of one epoch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum FixStatus {
    None,
    Single,
    Float,
    Fixed,
}

/// One-σ error of a status: per horizontal axis and vertical, metres, and its correlation
/// time, seconds.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ErrorModel {
    pub sigma_h_m: f64,
    pub sigma_v_m: f64,
    pub tau_s: f64,
}

/// The receiver's parameters (`[sensors.gnss]`); each default names its source.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct GnssConfig {
    pub profile: GnssProfile,
    /// Epochs per second. u-blox ZED-F9P: 1 Hz by default, up to 20 Hz with RTK (datasheet
    /// UBX-17051259); 5 Hz is a common robot setting.
    pub rate_hz: f64,
    /// From the epoch to the message being available, seconds (the receiver's solution and
    /// the serial link; u-blox states < 100 ms for the PVT output: 0.05 here).
    pub latency_s: f64,
    /// The antenna on a mast, base frame: 1.7 m up, about the canopy's top at full growth.
    pub mount_xyz_m: [f64; 3],
    /// Satellites below this elevation are not tracked, degrees (the usual receiver mask).
    pub elevation_mask_deg: f64,
    /// Satellites in the sky, over the whole sphere (GPS's 31 operational satellites: some
    /// 12 above a 10° mask at a time).
    pub satellites: usize,
    /// RTK: satellites needed for a carrier-phase solution (four double differences).
    pub rtk_min_satellites: usize,
    /// RTK: the largest PDOP at which the receiver keeps an RTK solution.
    pub rtk_max_pdop: f64,
    /// RTK: seconds of uninterrupted RTK conditions from float to fixed (ZED-F9P: < 10 s).
    pub rtk_fix_after_s: f64,
    /// RTK fixed: ZED-F9P 0.01 m + 1 ppm CEP horizontal (σ per axis = CEP / 1.1774 at a
    /// short baseline: 0.0085 m) and 0.01 m + 1 ppm R50 vertical (σ = R50 / 0.6745:
    /// 0.015 m); carrier-phase noise decorrelates within seconds (1 s).
    pub fixed: ErrorModel,
    /// RTK float: decimetres (the ambiguities unresolved; 0.2 m per axis, twice up, over
    /// tens of seconds).
    pub float: ErrorModel,
    /// Single-point, the RTK receiver without corrections: ZED-F9P's standalone 1.5 m CEP
    /// (σ 1.27 m per axis), twice vertically.
    pub single: ErrorModel,
    /// Single-point, the consumer receiver: u-blox NEO-M8N 2.5 m CEP (σ 2.12 m per axis),
    /// twice vertically; correlated over about a minute (D. L. Wilson's measured
    /// autocorrelation of a consumer receiver's horizontal error bends at ~1 min; Soundy
    /// et al., Sensors 20(21) 6050, 2020, find stationary single-frequency errors
    /// Ornstein–Uhlenbeck rather than white).
    pub consumer: ErrorModel,
    /// The world origin on the Earth: WGS-84 latitude and longitude (degrees) and
    /// ellipsoidal height (m); the world frame is east-north-up there. The default is the
    /// paper's Riseholme vineyard, as LCAS/bacchus_lcas (branch `gnss`) sets its datum
    /// (`mel_amcl/config/datums/riseholme.yaml`: 53.268642038 N, 0.524509505881 W; that
    /// file gives no height: 0).
    pub datum: [f64; 3],
    /// Every satellite above the mask counts as in view, whatever hides it: a receiver
    /// under an open sky along the whole route (the study's "RTK always fixed" cell), not a
    /// place in this world.
    pub open_sky: bool,
}

impl Default for GnssConfig {
    fn default() -> Self {
        Self {
            profile: GnssProfile::None,
            rate_hz: 5.0,
            latency_s: 0.05,
            mount_xyz_m: [0.0, 0.0, 1.7],
            elevation_mask_deg: 10.0,
            satellites: 31,
            rtk_min_satellites: 5,
            rtk_max_pdop: 6.0,
            rtk_fix_after_s: 10.0,
            datum: [53.268642038, -0.524509505881, 0.0],
            open_sky: false,
            fixed: ErrorModel {
                sigma_h_m: 0.0085,
                sigma_v_m: 0.015,
                tau_s: 1.0,
            },
            float: ErrorModel {
                sigma_h_m: 0.2,
                sigma_v_m: 0.4,
                tau_s: 30.0,
            },
            single: ErrorModel {
                sigma_h_m: 1.27,
                sigma_v_m: 2.54,
                tau_s: 60.0,
            },
            consumer: ErrorModel {
                sigma_h_m: 2.12,
                sigma_v_m: 4.25,
                tau_s: 60.0,
            },
        }
    }
}

impl GnssConfig {
    /// No receiver: the world's resolved file leaves the table out (so that worlds without
    /// GNSS keep their keys).
    pub fn is_absent(&self) -> bool {
        self.profile == GnssProfile::None
    }

    /// Why these parameters cannot work, if they cannot.
    pub fn check(&self) -> Result<(), String> {
        if self.profile == GnssProfile::None {
            return Ok(());
        }
        let models = [
            ("fixed", self.fixed),
            ("float", self.float),
            ("single", self.single),
            ("consumer", self.consumer),
        ];
        for (name, m) in models {
            if !(m.sigma_h_m >= 0.0 && m.sigma_v_m >= 0.0 && m.tau_s > 0.0 && m.tau_s.is_finite()) {
                return Err(format!(
                    "sensors.gnss.{name}: sigma_h_m and sigma_v_m >= 0, tau_s > 0"
                ));
            }
        }
        if !(self.rate_hz > 0.0 && self.rate_hz <= 100.0) {
            return Err(format!(
                "sensors.gnss.rate_hz = {}: between 0 and 100",
                self.rate_hz
            ));
        }
        if !(self.latency_s >= 0.0 && self.latency_s < 10.0) {
            return Err(format!(
                "sensors.gnss.latency_s = {}: between 0 and 10",
                self.latency_s
            ));
        }
        if !(0.0..90.0).contains(&self.elevation_mask_deg) {
            return Err("sensors.gnss.elevation_mask_deg: from 0 to 90".into());
        }
        let [lat, lon, h] = self.datum;
        if !((-90.0..=90.0).contains(&lat)
            && (-180.0..=180.0).contains(&lon)
            && h.is_finite()
            && h.abs() < 1e5)
        {
            return Err(
                "sensors.gnss.datum: [latitude from -90 to 90, longitude from -180 to 180, height in m]"
                    .into(),
            );
        }
        if self.satellites == 0 || self.satellites > 200 {
            return Err("sensors.gnss.satellites: from 1 to 200".into());
        }
        if self.rtk_min_satellites < 4
            || self.rtk_max_pdop.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater)
            || self.rtk_fix_after_s < 0.0
        {
            return Err(
                "sensors.gnss: rtk_min_satellites >= 4, rtk_max_pdop > 0, rtk_fix_after_s >= 0"
                    .into(),
            );
        }
        Ok(())
    }

    fn error_model(&self, status: FixStatus) -> Option<ErrorModel> {
        match (self.profile, status) {
            (_, FixStatus::None) | (GnssProfile::None, _) => None,
            (_, FixStatus::Fixed) => Some(self.fixed),
            (_, FixStatus::Float) => Some(self.float),
            (GnssProfile::Consumer, FixStatus::Single) => Some(self.consumer),
            (GnssProfile::Rtk, FixStatus::Single) => Some(self.single),
        }
    }
}

/// One satellite's track: its direction at time 0 (east-north-up, unit) turning about a
/// fixed axis.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Track {
    start: Vector3<f64>,
    axis: Unit<Vector3<f64>>,
}

/// The sky: every satellite's direction over time.
#[derive(Debug, Clone, PartialEq)]
pub struct Constellation {
    tracks: Vec<Track>,
    rate_rps: f64,
}

fn unit_vector(rng: &mut SimRng) -> Vector3<f64> {
    // Uniform on the sphere: z uniform in [-1, 1], azimuth uniform (Archimedes).
    let z: f64 = rng.random_range(-1.0..1.0);
    let phi: f64 = rng.random_range(0.0..std::f64::consts::TAU);
    let r = (1.0 - z * z).max(0.0).sqrt();
    Vector3::new(r * phi.cos(), r * phi.sin(), z)
}

impl Constellation {
    /// `count` satellites drawn from `rng`, each orbiting once per [`GPS_ORBIT_S`].
    pub fn new(count: usize, rng: &mut SimRng) -> Self {
        let tracks = (0..count)
            .map(|_| {
                let start = unit_vector(rng);
                // An axis perpendicular to the start: a great circle through it.
                let any = unit_vector(rng);
                let axis = start.cross(&any);
                let axis = if axis.norm() > 1e-9 {
                    Unit::new_normalize(axis)
                } else {
                    Unit::new_normalize(start.cross(&Vector3::x()) + Vector3::new(0.0, 1e-3, 0.0))
                };
                Track { start, axis }
            })
            .collect();
        Self {
            tracks,
            rate_rps: std::f64::consts::TAU / GPS_ORBIT_S,
        }
    }

    /// Every satellite's direction (east-north-up, unit) at `t_s`.
    pub fn directions(&self, t_s: f64) -> Vec<Vector3<f64>> {
        self.tracks
            .iter()
            .map(|k| UnitQuaternion::from_axis_angle(&k.axis, self.rate_rps * t_s) * k.start)
            .collect()
    }
}

/// Dilutions of precision of satellites in these directions (east-north-up, unit):
/// `(HDOP, VDOP, PDOP)`, `None` with fewer than 4 or a singular geometry.
pub fn dops(directions: &[Vector3<f64>]) -> Option<(f64, f64, f64)> {
    if directions.len() < 4 {
        return None;
    }
    let mut normal = Matrix4::zeros();
    for e in directions {
        let row = nalgebra::Vector4::new(-e.x, -e.y, -e.z, 1.0);
        normal += row * row.transpose();
    }
    let q = normal.try_inverse()?;
    let (ee, nn, uu) = (q[(0, 0)], q[(1, 1)], q[(2, 2)]);
    if !(ee >= 0.0 && nn >= 0.0 && uu >= 0.0 && (ee + nn + uu).is_finite()) {
        return None;
    }
    Some(((ee + nn).sqrt(), uu.sqrt(), (ee + nn + uu).sqrt()))
}

/// What the receiver reports at one epoch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GnssFix {
    pub stamp_ns: i64,
    pub status: FixStatus,
    /// The antenna's position as measured, east-north-up in the world frame, metres; `None`
    /// without a fix.
    pub position_enu_m: Option<Vector3<f64>>,
    /// The reported variances east, north, up, m² (zero without a fix).
    pub variance_enu_m2: [f64; 3],
    /// Satellites tracked above the mask and visible.
    pub satellites: usize,
    /// Dilutions of precision of the visible satellites (`None` under 4).
    pub hdop: Option<f64>,
    pub vdop: Option<f64>,
    /// The same position as WGS-84 latitude, longitude (degrees) and ellipsoidal height
    /// (m), from the configuration's datum; `None` without a fix.
    pub geodetic: Option<[f64; 3]>,
    /// From the epoch to the fix being available (the receiver's latency), ns.
    pub latency_ns: i64,
}

/// The receiver: its sky, its fix state and its errors.
#[derive(Debug, Clone)]
pub struct GnssReceiver {
    cfg: GnssConfig,
    sky: Constellation,
    rng: SimRng,
    /// Unit-variance Gauss–Markov states per status (fixed, float, single): east, north, up.
    states: [Vector3<f64>; 3],
    /// The last epoch's stamp.
    last_ns: Option<i64>,
    /// Since when RTK conditions have held without a break.
    rtk_since_ns: Option<i64>,
}

fn gaussian(rng: &mut SimRng) -> f64 {
    <StandardNormal as Distribution<f64>>::sample(&StandardNormal, rng)
}

fn slot(status: FixStatus) -> Option<usize> {
    match status {
        FixStatus::Fixed => Some(0),
        FixStatus::Float => Some(1),
        FixStatus::Single => Some(2),
        FixStatus::None => None,
    }
}

impl GnssReceiver {
    /// A receiver whose sky and errors are drawn from `rng` (the run's `gnss` stream).
    pub fn new(cfg: &GnssConfig, mut rng: SimRng) -> Self {
        let sky = Constellation::new(cfg.satellites, &mut rng);
        let states = std::array::from_fn(|_| Vector3::from_fn(|_, _| gaussian(&mut rng)));
        Self {
            cfg: cfg.clone(),
            sky,
            rng,
            states,
            last_ns: None,
            rtk_since_ns: None,
        }
    }

    pub fn constellation(&self) -> &Constellation {
        &self.sky
    }

    /// The directions (east-north-up, unit) of the satellites above the mask at `t_ns`.
    pub fn tracked(&self, t_ns: i64) -> Vec<Vector3<f64>> {
        let min_up = self.cfg.elevation_mask_deg.to_radians().sin();
        self.sky
            .directions(t_ns as f64 * 1e-9)
            .into_iter()
            .filter(|d| d.z >= min_up)
            .collect()
    }

    /// The epoch at `t_ns` of an antenna truly at `antenna_enu_m`, where `visible(direction)`
    /// says whether a ray from the antenna reaches the sky that way. Epochs come in time
    /// order.
    pub fn measure(
        &mut self,
        t_ns: i64,
        antenna_enu_m: &Vector3<f64>,
        mut visible: impl FnMut(&Vector3<f64>) -> bool,
    ) -> GnssFix {
        let seen: Vec<Vector3<f64>> = self
            .tracked(t_ns)
            .into_iter()
            .filter(|d| visible(d))
            .collect();
        let geometry = dops(&seen);
        // Advance every status's error to this epoch.
        let dt_s = self
            .last_ns
            .map_or(f64::INFINITY, |l| (t_ns - l) as f64 * 1e-9);
        self.last_ns = Some(t_ns);
        for status in [FixStatus::Fixed, FixStatus::Float, FixStatus::Single] {
            let i = slot(status).expect("a fix");
            let tau = self.cfg.error_model(status).map_or(1.0, |m| m.tau_s);
            let phi = (-dt_s / tau).exp();
            let spread = (1.0 - phi * phi).max(0.0).sqrt();
            let draw = Vector3::from_fn(|_, _| gaussian(&mut self.rng));
            self.states[i] = self.states[i] * phi + draw * spread;
        }
        let status = match (self.cfg.profile, geometry) {
            (GnssProfile::None, _) | (_, None) => {
                self.rtk_since_ns = None;
                FixStatus::None
            }
            (GnssProfile::Consumer, Some(_)) => FixStatus::Single,
            (GnssProfile::Rtk, Some((_, _, pdop))) => {
                if seen.len() >= self.cfg.rtk_min_satellites && pdop <= self.cfg.rtk_max_pdop {
                    let since = *self.rtk_since_ns.get_or_insert(t_ns);
                    if (t_ns - since) as f64 * 1e-9 >= self.cfg.rtk_fix_after_s {
                        FixStatus::Fixed
                    } else {
                        FixStatus::Float
                    }
                } else {
                    self.rtk_since_ns = None;
                    FixStatus::Single
                }
            }
        };
        let (hdop, vdop) = geometry.map_or((None, None), |(h, v, _)| (Some(h), Some(v)));
        let (position_enu_m, variance_enu_m2) = match (self.cfg.error_model(status), slot(status)) {
            (Some(m), Some(i)) => {
                let sh = m.sigma_h_m * hdop.unwrap_or(1.0).max(1.0);
                let sv = m.sigma_v_m * vdop.unwrap_or(1.0).max(1.0);
                let u = self.states[i];
                (
                    Some(antenna_enu_m + Vector3::new(sh * u.x, sh * u.y, sv * u.z)),
                    [sh * sh, sh * sh, sv * sv],
                )
            }
            _ => (None, [0.0; 3]),
        };
        GnssFix {
            stamp_ns: t_ns,
            status,
            position_enu_m,
            variance_enu_m2,
            satellites: seen.len(),
            hdop,
            vdop,
            geodetic: position_enu_m.map(|p| geodetic_from_enu(self.cfg.datum, &p)),
            latency_ns: 0,
        }
    }
}

impl GnssReceiver {
    /// The epoch at `t_ns` of the antenna at `base_from_antenna` on the robot of `scene`,
    /// the sky seen past the world's mesh ([`sky_visible`]); and the antenna's true
    /// position.
    pub fn measure_scene(
        &mut self,
        scene: &Scene<'_>,
        t_ns: i64,
        base_from_antenna: &Isometry3<f64>,
    ) -> (GnssFix, Vector3<f64>) {
        let world_from_antenna = scene.trajectory.state(t_ns).world_from_base * base_from_antenna;
        let antenna = world_from_antenna.translation.vector;
        let fix = self.measure(t_ns, &antenna, |d| sky_visible(scene.caster, &antenna, d));
        (fix, antenna)
    }
}

/// WGS-84's semi-major axis (m) and first eccentricity squared (NIMA TR8350.2).
const WGS84_A: f64 = 6_378_137.0;
const WGS84_E2: f64 = 6.694_379_990_14e-3;

/// Earth-centred, Earth-fixed coordinates of a geodetic point (degrees, degrees, m).
fn ecef_from_geodetic([lat, lon, h]: [f64; 3]) -> Vector3<f64> {
    let (phi, lambda) = (lat.to_radians(), lon.to_radians());
    let n = WGS84_A / (1.0 - WGS84_E2 * phi.sin().powi(2)).sqrt();
    Vector3::new(
        (n + h) * phi.cos() * lambda.cos(),
        (n + h) * phi.cos() * lambda.sin(),
        (n * (1.0 - WGS84_E2) + h) * phi.sin(),
    )
}

/// The rotation from east-north-up at `(lat, lon)` to ECEF: its columns are east, north, up.
fn ecef_r_enu(lat: f64, lon: f64) -> nalgebra::Matrix3<f64> {
    let (sp, cp) = lat.to_radians().sin_cos();
    let (sl, cl) = lon.to_radians().sin_cos();
    nalgebra::Matrix3::new(-sl, -sp * cl, cp * cl, cl, -sp * sl, cp * sl, 0.0, cp, sp)
}

/// The geodetic point (latitude, longitude in degrees, ellipsoidal height in m) of
/// `enu_m`, east-north-up from `datum`: through ECEF, and back by Bowring's iteration
/// (five rounds: converged to far under a millimetre near the surface).
pub fn geodetic_from_enu(datum: [f64; 3], enu_m: &Vector3<f64>) -> [f64; 3] {
    let ecef = ecef_from_geodetic(datum) + ecef_r_enu(datum[0], datum[1]) * enu_m;
    let p = ecef.x.hypot(ecef.y);
    let lon = ecef.y.atan2(ecef.x);
    let mut lat = ecef.z.atan2(p * (1.0 - WGS84_E2));
    let mut h = 0.0;
    for _ in 0..5 {
        let n = WGS84_A / (1.0 - WGS84_E2 * lat.sin().powi(2)).sqrt();
        h = p / lat.cos() - n;
        lat = ecef.z.atan2(p * (1.0 - WGS84_E2 * n / (n + h)));
    }
    [lat.to_degrees(), lon.to_degrees(), h]
}

/// East-north-up from `datum` of a geodetic point: the inverse of [`geodetic_from_enu`].
pub fn enu_from_geodetic(datum: [f64; 3], point: [f64; 3]) -> Vector3<f64> {
    ecef_r_enu(datum[0], datum[1]).transpose()
        * (ecef_from_geodetic(point) - ecef_from_geodetic(datum))
}

/// The receiver as a sensor of the stream: an epoch every `1 / rate_hz` s, measured with
/// the antenna where the mount puts it on the robot, available `latency_s` later.
#[derive(Debug)]
pub struct GnssSensor {
    receiver: GnssReceiver,
    base_from_antenna: Isometry3<f64>,
    rate_hz: f64,
    latency_ns: i64,
    open_sky: bool,
    k: u64,
    end_ns: i64,
}

impl GnssSensor {
    pub fn new(cfg: &GnssConfig, end_ns: i64, rng: SimRng) -> Self {
        let [x, y, z] = cfg.mount_xyz_m;
        Self {
            receiver: GnssReceiver::new(cfg, rng),
            base_from_antenna: Isometry3::translation(x, y, z),
            rate_hz: cfg.rate_hz,
            latency_ns: (cfg.latency_s * 1e9).round() as i64,
            open_sky: cfg.open_sky,
            k: 0,
            end_ns,
        }
    }
}

impl super::Sensor for GnssSensor {
    fn next_ready_ns(&self) -> Option<i64> {
        let t = super::sample_time_ns(self.k, self.rate_hz);
        (t <= self.end_ns).then_some(t + self.latency_ns)
    }

    fn emit(&mut self, scene: &Scene<'_>) -> super::Message {
        let t = super::sample_time_ns(self.k, self.rate_hz);
        self.k += 1;
        let mut fix = if self.open_sky {
            let antenna = (scene.trajectory.state(t).world_from_base * self.base_from_antenna)
                .translation
                .vector;
            self.receiver.measure(t, &antenna, |_| true)
        } else {
            self.receiver
                .measure_scene(scene, t, &self.base_from_antenna)
                .0
        };
        fix.latency_ns = self.latency_ns;
        super::Message::Gnss(fix)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn receiver(profile: GnssProfile) -> GnssReceiver {
        let cfg = GnssConfig {
            profile,
            ..GnssConfig::default()
        };
        cfg.check().expect("valid");
        GnssReceiver::new(&cfg, crate::rng::stream(7, "gnss"))
    }

    /// Sample mean, standard deviation and the autocorrelation at `lag` epochs.
    fn stats(xs: &[f64], lag: usize) -> (f64, f64, f64) {
        let n = xs.len() as f64;
        let mean = xs.iter().sum::<f64>() / n;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
        let cov = xs
            .windows(lag + 1)
            .map(|w| (w[0] - mean) * (w[lag] - mean))
            .sum::<f64>()
            / (n - lag as f64);
        (mean, var.sqrt(), cov / var)
    }

    /// Over ten hours at one place under an open sky, a consumer receiver's error is the
    /// profile's process: divided by the σ it reports (the profile's σ, scaled by the DOP
    /// where that exceeds 1: checked at every epoch), it has mean zero, unit spread, and
    /// correlation e⁻¹ after τ and none after 10 τ. The bounds are the estimators' own
    /// spread: with τ = 60 s ten hours hold some 300 independent stretches (the mean's
    /// standard error 1/17), so each check allows about four of those standard errors.
    #[test]
    fn a_static_open_sky_run_has_the_profiles_statistics() {
        let mut rx = receiver(GnssProfile::Consumer);
        let m = GnssConfig::default().consumer;
        let truth = Vector3::new(10.0, -4.0, 0.5);
        let rate = 5.0;
        let n = (10.0 * 3600.0 * rate) as usize;
        let (mut east, mut up) = (Vec::with_capacity(n), Vec::with_capacity(n));
        for k in 0..n {
            let t_ns = (k as f64 * 1e9 / rate) as i64;
            let fix = rx.measure(t_ns, &truth, |_| true);
            assert_eq!(fix.status, FixStatus::Single);
            let (h, v) = (fix.hdop.expect("dop"), fix.vdop.expect("dop"));
            let (sh, sv) = (fix.variance_enu_m2[0].sqrt(), fix.variance_enu_m2[2].sqrt());
            assert!(
                (sh - m.sigma_h_m * h.max(1.0)).abs() < 1e-12,
                "{sh} at HDOP {h}"
            );
            assert!(
                (sv - m.sigma_v_m * v.max(1.0)).abs() < 1e-12,
                "{sv} at VDOP {v}"
            );
            let p = fix.position_enu_m.expect("a fix");
            east.push((p.x - truth.x) / sh);
            up.push((p.z - truth.z) / sv);
        }
        let tau_lag = (m.tau_s * rate) as usize;
        let independent = (n as f64 / rate) / (2.0 * m.tau_s);
        for (axis, xs) in [("east", &east), ("up", &up)] {
            let (mean, sigma, rho) = stats(xs, tau_lag);
            assert!(
                mean.abs() < 4.0 / independent.sqrt(),
                "{axis}: mean {mean} σ"
            );
            assert!((sigma - 1.0).abs() < 0.12, "{axis}: spread {sigma} σ");
            assert!(
                (rho - (-1.0f64).exp()).abs() < 0.1,
                "{axis}: correlation after τ {rho}"
            );
            let (_, _, rho10) = stats(xs, 10 * tau_lag);
            assert!(rho10.abs() < 0.1, "{axis}: correlation after 10 τ {rho10}");
        }
    }

    /// A wall that hides the sky below 60° of elevation, raised for a minute and lowered:
    /// an RTK receiver fixed before loses its fix behind it, and is fixed again only
    /// `rtk_fix_after_s` after the wall is gone, float meanwhile.
    #[test]
    fn the_fix_drops_behind_a_wall_and_refixes_after_it() {
        let mut rx = receiver(GnssProfile::Rtk);
        let cfg = GnssConfig::default();
        let at = Vector3::zeros();
        let wall = |t_s: f64| (60.0..120.0).contains(&t_s);
        let hide_below = 60f64.to_radians().sin();
        let mut history = Vec::new();
        for k in 0..(200 * 5) {
            let t_s = k as f64 / 5.0;
            let fix = rx.measure((t_s * 1e9) as i64, &at, |d| !wall(t_s) || d.z >= hide_below);
            history.push((t_s, fix));
        }
        let status_at = |t: f64| {
            history
                .iter()
                .find(|(s, _)| (*s - t).abs() < 1e-9)
                .expect("epoch")
                .1
                .status
        };
        // Open sky: float for the first 10 s, then fixed.
        assert_eq!(status_at(0.0), FixStatus::Float);
        assert_eq!(status_at(cfg.rtk_fix_after_s + 0.2), FixStatus::Fixed);
        assert_eq!(status_at(59.8), FixStatus::Fixed);
        // Behind the wall: too few satellites above 60° for RTK.
        for (t, fix) in history.iter().filter(|(t, _)| wall(*t)) {
            assert!(fix.status < FixStatus::Float, "{t} s: {fix:?}");
            assert!(fix.satellites < cfg.rtk_min_satellites, "{t} s: {fix:?}");
        }
        // After it: float until the ambiguities are resolved again, then fixed.
        assert_eq!(status_at(120.0), FixStatus::Float);
        assert_eq!(
            status_at(120.0 + cfg.rtk_fix_after_s - 0.2),
            FixStatus::Float
        );
        assert_eq!(status_at(120.0 + cfg.rtk_fix_after_s), FixStatus::Fixed);
        // The fixed error is centimetres, the single one metres.
        let fixed_err = history
            .iter()
            .filter(|(_, f)| f.status == FixStatus::Fixed)
            .map(|(_, f)| f.position_enu_m.expect("fix").xy().norm())
            .fold(0.0, f64::max);
        assert!(fixed_err < 0.06, "fixed, worst {fixed_err} m");
    }

    /// The sky has GPS's count above the mask and moves a few degrees in a ten-minute run.
    #[test]
    fn the_sky_holds_about_a_dozen_satellites_and_moves_slowly() {
        let rx = receiver(GnssProfile::Rtk);
        let n = rx.tracked(0).len();
        assert!((7..=20).contains(&n), "{n} above the mask");
        let (a, b) = (
            rx.constellation().directions(0.0),
            rx.constellation().directions(600.0),
        );
        let moved = a
            .iter()
            .zip(&b)
            .map(|(x, y)| x.angle(y).to_degrees())
            .fold(0.0, f64::max);
        assert!((1.0..10.0).contains(&moved), "moved {moved}° in 10 min");
    }

    /// The sky is seen past the mesh: under a roof 3 m up and 20 m wide nothing high is
    /// seen and the receiver has no fix; beside it, the satellites on the roof's side are
    /// hidden and the others seen.
    #[test]
    fn a_roof_hides_the_sky_above_it() {
        use crate::raycast::BruteForce;
        use crate::world::{Material, Mesh};
        let mut mesh = Mesh::new();
        let v: Vec<u32> = [[-10.0, -10.0], [10.0, -10.0], [10.0, 10.0], [-10.0, 10.0]]
            .iter()
            .map(|[x, y]| mesh.push_vertex(Point3::new(*x, *y, 3.0)))
            .collect();
        mesh.push_triangle([v[0], v[1], v[2]], Material::Leaf);
        mesh.push_triangle([v[0], v[2], v[3]], Material::Leaf);
        let caster = BruteForce::build(&mesh);
        let under = Vector3::zeros();
        assert!(!sky_visible(&caster, &under, &Vector3::z()));
        // 5° up: the roof's edge, 10 m away, is 0.87 m up at it: seen past.
        let low = Vector3::new(5f64.to_radians().cos(), 0.0, 5f64.to_radians().sin());
        assert!(sky_visible(&caster, &under, &low));
        let mut rx = receiver(GnssProfile::Rtk);
        let fix = rx.measure(0, &under, |d| sky_visible(&caster, &under, d));
        assert_eq!(fix.status, FixStatus::None, "{fix:?}");
        assert!(fix.position_enu_m.is_none());
        // 12 m east of the roof's edge: the sky to the west below atan(3/12) is hidden.
        let beside = Vector3::new(22.0, 0.0, 0.0);
        let west_low = Vector3::new(-1.0, 0.0, 0.2).normalize();
        let west_high = Vector3::new(-1.0, 0.0, 0.3).normalize();
        assert!(!sky_visible(&caster, &beside, &west_low));
        assert!(sky_visible(&caster, &beside, &west_high));
    }

    #[test]
    fn dops_of_a_good_and_a_degenerate_sky() {
        let good = [
            Vector3::new(0.0, 0.0, 1.0),
            Vector3::new(1.0, 0.0, 0.2).normalize(),
            Vector3::new(-0.5, 0.87, 0.2).normalize(),
            Vector3::new(-0.5, -0.87, 0.2).normalize(),
        ];
        let (h, v, p) = dops(&good).expect("four satellites");
        assert!(h > 0.5 && h < 3.0 && v > 0.5 && v < 5.0, "{h} {v}");
        assert!((p * p - h * h - v * v).abs() < 1e-9);
        assert!(dops(&good[..3]).is_none(), "three satellites");
        let same = [good[0]; 4];
        assert!(dops(&same).is_none(), "one direction four times");
    }

    /// The datum conversion against a known length: one degree of latitude north of the
    /// Riseholme datum is the WGS-84 meridian arc there (111.30 km, within 10 m), and
    /// every point comes back from latitude, longitude and height to within 1 µm.
    #[test]
    fn east_north_up_and_wgs84_convert_both_ways() {
        let datum = GnssConfig::default().datum;
        let north = enu_from_geodetic(datum, [datum[0] + 1.0, datum[1], datum[2]]);
        // The meridian arc of that degree, M(φ) = a(1 − e²)/(1 − e² sin²φ)^{3/2} at the
        // mid-latitude (111.30 km here); the chord is shorter by about 1.4 m.
        let mid = (datum[0] + 0.5).to_radians();
        let arc = WGS84_A * (1.0 - WGS84_E2) / (1.0 - WGS84_E2 * mid.sin().powi(2)).powf(1.5)
            * 1f64.to_radians();
        assert!(
            (north.y - arc).abs() < 10.0,
            "{north} against an arc of {arc}"
        );
        assert!(north.x.abs() < 1e-6, "{north}");
        for p in [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(35.0, -120.0, 1.7),
            Vector3::new(-2500.0, 4000.0, -30.0),
        ] {
            let g = geodetic_from_enu(datum, &p);
            let back = enu_from_geodetic(datum, g);
            assert!((back - p).norm() < 1e-6, "{p} -> {g:?} -> {back}");
        }
        let up = geodetic_from_enu(datum, &Vector3::new(0.0, 0.0, 10.0));
        assert!((up[2] - 10.0).abs() < 1e-6 && (up[0] - datum[0]).abs() < 1e-9);
    }

    #[test]
    fn bad_parameters_are_named() {
        let cfg = GnssConfig {
            profile: GnssProfile::Rtk,
            rate_hz: 0.0,
            ..GnssConfig::default()
        };
        assert!(cfg.check().expect_err("rate").contains("rate_hz"));
        let cfg = GnssConfig {
            profile: GnssProfile::Rtk,
            float: ErrorModel {
                sigma_h_m: 0.2,
                sigma_v_m: 0.4,
                tau_s: 0.0,
            },
            ..GnssConfig::default()
        };
        assert!(cfg.check().expect_err("tau").contains("sensors.gnss.float"));
    }
}
