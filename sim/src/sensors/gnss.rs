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
//! - **Reflections** (`reflections`, on by default; never under `open_sky`). Each tracked
//!   satellite's signal reaches the antenna along a [`Path`] ([`receive`]): the direct ray,
//!   and a reflection off a near-vertical surface (canopy wall, post, wire, fence panel),
//!   looked for by a ray from the antenna towards the mirror direction (the satellite's
//!   azimuth + 180°, the same elevation): if it meets a surface within
//!   `reflection_range_m` and that point sees the satellite, the reflected signal arrives
//!   with an extra path `2·d·cos(el)` for a reflector at horizontal distance `d` (the image
//!   geometry of a vertical reflector: Groves, *Principles of GNSS, Inertial and Multisensor
//!   Integrated Navigation Systems*, 2nd ed., 2013, on NLOS reception; Hsu, GPS Solutions
//!   22:7, 2018, models the NLOS delay from the same distance and elevation). A satellite
//!   whose direct ray is blocked but which is reflected is received non-line-of-sight
//!   (NLOS): code and carrier both late by the whole extra path. A visible one with a
//!   reflector carries multipath of relative amplitude `α` (`reflection_amplitude`) and
//!   phase `θ = 2π·Δ/λ + π` (the geometry's, deterministic; `π` for a dielectric's
//!   reflection): carrier error `λ/2π · atan2(α sin θ, 1 + α cos θ)`, at most `λ/4`
//!   (Georgiadou & Kleusberg, manuscripta geodaetica 13:172, 1988); code error the
//!   coherent early-minus-late DLL's lock point ([`dll_error_chips`]) with a narrow
//!   correlator (van Dierendonck, Fenton & Ford, NAVIGATION 39(3), 1992), within its
//!   multipath error envelope (Braasch, ch. 14 of Parkinson & Spilker, *Global Positioning
//!   System: Theory and Applications* vol. I, 1996).
//! - **Solution under reflections.** The range biases `b` of the satellites used move the
//!   least-squares position by `Δx = (GᵀG)⁻¹Gᵀb` (the rows `[-e, 1]` of the DOPs):
//!   single fixes with the code biases, RTK float and fixed with the carrier ones. NLOS
//!   satellites count for a float solution but not for a fix: fixed needs
//!   `rtk_min_satellites` line-of-sight ones with a PDOP under `rtk_max_pdop`, held for
//!   `rtk_fix_after_s`, and its solution is theirs alone (partial ambiguity resolution
//!   fixes the subset that validates, Teunissen, Joosten & Tiberius, ION NTM 1999; that an
//!   NLOS satellite's ambiguity, biased by metres that change as the antenna moves, is not
//!   in it is this model's assumption). The reported covariance stays the receiver's own
//!   estimate above: it does not know it is fooled, so near a reflector the error exceeds
//!   the σ it reports.
//!
//! What is not modelled yet: more than one reflection per satellite, the reflector's true
//! orientation (every surface met is taken as facing the satellite), its size and material
//! (a post or wire, narrower than the first Fresnel zone, reflects less), diffraction and
//! attenuation by foliage, the antenna's gain and polarisation pattern (which would weaken
//! reflections further), a signal-strength threshold for tracking weak NLOS signals,
//! multipath at an RTK base, the antenna's phase-centre variation, and correlation between
//! the axes.

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

/// The speed of light, m/s (IS-GPS-200's value).
const LIGHT_M_S: f64 = 299_792_458.0;

/// GPS L1's carrier wavelength, m: c / 1575.42 MHz (IS-GPS-200): 0.190 m.
pub const L1_WAVELENGTH_M: f64 = LIGHT_M_S / 1575.42e6;

/// One chip of the C/A code, m: c / 1.023 Mchip/s (IS-GPS-200): 293 m.
pub const CA_CHIP_M: f64 = LIGHT_M_S / 1.023e6;

/// The distance along a unit `direction` from `origin` (world frame) to the first surface
/// the caster holds, if one lies within `reach` m.
pub fn first_hit(
    caster: &dyn RayCaster,
    origin: &Vector3<f64>,
    direction: &Vector3<f64>,
    reach: f64,
) -> Option<f64> {
    let o = Point3::from(origin.cast::<f32>());
    let dir = direction.normalize().cast::<f32>();
    caster
        .cast(&o, &dir, 1e-3, reach as f32)
        .map(|h| f64::from(h.t))
}

/// How a tracked satellite's signal reaches the antenna.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Path {
    /// The direct ray alone.
    Direct,
    /// The direct ray and a reflection `delay_m` longer (multipath).
    Multipath { delay_m: f64 },
    /// A reflection alone, `delay_m` longer than the blocked direct ray (non-line-of-sight).
    Nlos { delay_m: f64 },
}

/// Which measurement a solution rests on: the code (single point) or the carrier (RTK).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Observable {
    Code,
    Carrier,
}

/// A received satellite: its direction (east-north-up, unit) and how it arrives.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reception {
    pub direction: Vector3<f64>,
    pub path: Path,
}

impl Reception {
    /// Its range error, m, on `observable`, for a reflection of relative amplitude `alpha`
    /// and a DLL of correlator spacing `spacing_chips`. NLOS: the whole extra path, on code
    /// and carrier (the only signal is the reflected one). Multipath: the composite
    /// signal's, with the reflection's phase `θ = 2π·Δ/λ + π` (its extra path in L1
    /// wavelengths, and half a turn for a reflection off a dielectric, whose Fresnel
    /// coefficient at normal incidence is negative): the carrier's
    /// `λ/2π · atan2(α sin θ, 1 + α cos θ)` (Georgiadou & Kleusberg 1988), never beyond
    /// `λ/4`; the code's, the DLL's lock point ([`dll_error_chips`]) with the reflection's
    /// part in phase with the carrier the PLL tracks (the composite's phase `ψ`):
    /// `a = α·cos(θ − ψ)/cos ψ = α(α + cos θ)/(1 + α cos θ)`, from `α` in phase (`θ = 0`)
    /// to `−α` against it (`θ = π`), the two edges of the error envelope.
    pub fn range_bias_m(&self, observable: Observable, alpha: f64, spacing_chips: f64) -> f64 {
        match self.path {
            Path::Direct => 0.0,
            Path::Nlos { delay_m } => delay_m,
            Path::Multipath { delay_m } => {
                let theta =
                    std::f64::consts::TAU * delay_m / L1_WAVELENGTH_M + std::f64::consts::PI;
                let (sin, cos) = theta.sin_cos();
                match observable {
                    Observable::Carrier => {
                        L1_WAVELENGTH_M / std::f64::consts::TAU
                            * (alpha * sin).atan2(1.0 + alpha * cos)
                    }
                    Observable::Code => {
                        let a = alpha * (alpha + cos) / (1.0 + alpha * cos);
                        CA_CHIP_M * dll_error_chips(a, delay_m / CA_CHIP_M, spacing_chips)
                    }
                }
            }
        }
    }
}

/// The autocorrelation of a spreading code at a lag of `x` chips (infinite bandwidth).
fn code_correlation(x: f64) -> f64 {
    (1.0 - x.abs()).max(0.0)
}

/// The tracking error, chips, of a coherent early-minus-late delay-lock loop with early and
/// late correlators `spacing` chips apart, when a reflection of in-phase relative amplitude
/// `a` (|a| < 1; negative against the direct signal) arrives `delay` chips after the
/// direct one: the zero of `D(τ) = R(τ−s/2) − R(τ+s/2) + a[R(τ−δ−s/2) − R(τ−δ+s/2)]`
/// nearest the direct signal's peak where `D` rises (the loop's stable lock point), `R` the
/// code's triangular autocorrelation (Braasch 1996; van Dierendonck et al. 1992). For
/// `δ < (1+a)s/2` it is `aδ/(1+a)`, then `a·s/2` until the reflection's correlation
/// leaves the correlators, and zero past `1 + s/2` chips. `D` is piecewise linear, so the
/// zero is found exactly between its corners.
pub fn dll_error_chips(a: f64, delay: f64, spacing: f64) -> f64 {
    let h = spacing / 2.0;
    let d = |x: f64| {
        code_correlation(x - h) - code_correlation(x + h)
            + a * (code_correlation(x - delay - h) - code_correlation(x - delay + h))
    };
    let mut corners: Vec<f64> = [0.0, delay]
        .iter()
        .flat_map(|c| [-h, h].map(move |s| c + s))
        .flat_map(|c| [c - 1.0, c, c + 1.0])
        .collect();
    corners.sort_by(f64::total_cmp);
    corners.dedup();
    let mut lock: Option<f64> = None;
    for w in corners.windows(2) {
        let (x0, x1) = (w[0], w[1]);
        let (d0, d1) = (d(x0), d(x1));
        if d0 <= 0.0 && d1 >= 0.0 && d1 > d0 {
            let x = x0 - d0 * (x1 - x0) / (d1 - d0);
            if lock.is_none_or(|l| x.abs() < l.abs()) {
                lock = Some(x);
            }
        }
    }
    lock.unwrap_or(0.0)
}

/// How each satellite in `directions` (east-north-up, unit) reaches an antenna at
/// `antenna`, those received in their order: `cast(origin, unit direction, reach)` is the
/// distance to the first surface along that ray within `reach` ([`first_hit`] against the
/// world). The direct ray is the antenna's towards the satellite ([`SKY_REACH_M`]); the
/// reflection is looked for along the mirror direction of a vertical reflector facing the
/// satellite (azimuth + 180°, the same elevation) within `range_m`, and counts if its
/// point sees the satellite. The extra path via a reflection point at `t` along that ray
/// is `t − t·(m·e) = 2·t·cos²(el) = 2·d·cos(el)`, `d` its horizontal distance.
pub fn receive(
    directions: &[Vector3<f64>],
    antenna: &Vector3<f64>,
    range_m: f64,
    mut cast: impl FnMut(&Vector3<f64>, &Vector3<f64>, f64) -> Option<f64>,
) -> Vec<Reception> {
    let mut out = Vec::with_capacity(directions.len());
    for e in directions {
        let direct = cast(antenna, e, f64::from(SKY_REACH_M)).is_none();
        let mirror = Vector3::new(-e.x, -e.y, e.z);
        let reflected = cast(antenna, &mirror, range_m).filter(|&t| {
            // From just before the surface, on the antenna's side.
            let point = antenna + mirror * (t - (0.01f64).min(t / 2.0));
            cast(&point, e, f64::from(SKY_REACH_M)).is_none()
        });
        let delay = |t: f64| t * (1.0 - mirror.dot(e));
        let path = match (direct, reflected) {
            (true, None) => Path::Direct,
            (true, Some(t)) => Path::Multipath { delay_m: delay(t) },
            (false, Some(t)) => Path::Nlos { delay_m: delay(t) },
            (false, None) => continue,
        };
        out.push(Reception {
            direction: *e,
            path,
        });
    }
    out
}

/// The position error, east-north-up, of the least-squares position-and-clock solution
/// from satellites in `directions` whose ranges are too long by `biases` (m):
/// `Δx = (GᵀG)⁻¹Gᵀb` with rows `[-e, 1]` (Misra & Enge §6.1); `None` with a singular
/// geometry.
pub fn position_error(directions: &[Vector3<f64>], biases: &[f64]) -> Option<Vector3<f64>> {
    let mut normal = Matrix4::zeros();
    let mut rhs = nalgebra::Vector4::zeros();
    for (e, b) in directions.iter().zip(biases) {
        let row = nalgebra::Vector4::new(-e.x, -e.y, -e.z, 1.0);
        normal += row * row.transpose();
        rhs += row * *b;
    }
    let x = normal.try_inverse()? * rhs;
    Some(x.xyz())
}

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

impl FixStatus {
    /// Every status, worst first (their order).
    pub const ALL: [FixStatus; 4] = [Self::None, Self::Single, Self::Float, Self::Fixed];

    /// The status as files and tables name it (its serde name).
    pub fn name(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Single => "single",
            Self::Float => "float",
            Self::Fixed => "fixed",
        }
    }

    /// The status named `name` ([`FixStatus::name`]).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|s| s.name() == name)
    }
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
    /// Multipath and non-line-of-sight reception off the world's surfaces (module doc).
    /// `false`: a blocked satellite is lost and a visible one exact, the fixes bit for bit
    /// those of the model before reflections. Never under `open_sky`.
    pub reflections: bool,
    /// The farthest reflector, m along the mirror ray. A surface reflects specularly where
    /// it covers the first Fresnel zone, of radius `√(λ·r)` at `r` from the antenna for a
    /// source at infinity (ITU-R P.526, the first Fresnel ellipsoid); the block's largest
    /// reflectors, a 1.7 m fence panel and a 1.9 m canopy wall, cover it out to
    /// `1.7² / 0.19 = 15 m` (the smaller of the two). Posts and wires, far narrower than the
    /// zone, would reflect much less than `α` at any range: the model takes every surface
    /// met alike.
    pub reflection_range_m: f64,
    /// The reflection's amplitude relative to the direct signal, `α` in `[0, 1)`: the
    /// Fresnel coefficient of wood (the posts and fence) at normal incidence at L1,
    /// `|1 − √ε| / (1 + √ε)` with ITU-R P.2040-1's wood (Table 3: `ε' = 1.99`, `σ = 0.0047
    /// f^1.0718` S/m, f in GHz): 0.17. The antenna's rejection of the reflection's flipped
    /// polarisation would lower it. One amplitude for every surface (leaves and steel
    /// wires too).
    pub reflection_amplitude: f64,
    /// Early-late correlator spacing of the code loop, chips: the narrow correlator's 0.1
    /// (van Dierendonck, Fenton & Ford, NAVIGATION 39(3), 1992), against the classic 1.
    pub correlator_spacing_chips: f64,
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
            reflections: true,
            reflection_range_m: 15.0,
            reflection_amplitude: 0.17,
            correlator_spacing_chips: 0.1,
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
        if !(self.reflection_range_m > 0.0 && self.reflection_range_m <= f64::from(SKY_REACH_M)) {
            return Err(format!(
                "sensors.gnss.reflection_range_m = {}: above 0, at most {SKY_REACH_M}",
                self.reflection_range_m
            ));
        }
        if !(0.0..1.0).contains(&self.reflection_amplitude) {
            return Err(format!(
                "sensors.gnss.reflection_amplitude = {}: from 0 to under 1",
                self.reflection_amplitude
            ));
        }
        if !(self.correlator_spacing_chips > 0.0 && self.correlator_spacing_chips <= 1.0) {
            return Err(format!(
                "sensors.gnss.correlator_spacing_chips = {}: above 0, at most 1",
                self.correlator_spacing_chips
            ));
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

    /// Satellites standing still in these directions (east-north-up): a sky for tests and
    /// tools.
    pub fn standing(directions: &[Vector3<f64>]) -> Self {
        let tracks = directions
            .iter()
            .map(|d| {
                let start = d.normalize();
                let other = if start.x.abs() < 0.9 {
                    Vector3::x()
                } else {
                    Vector3::y()
                };
                Track {
                    start,
                    axis: Unit::new_normalize(start.cross(&other)),
                }
            })
            .collect();
        Self {
            tracks,
            rate_rps: 0.0,
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
    /// Satellites in the solution: those above the mask received, directly or (NLOS) by a
    /// reflection; RTK fixed, those received directly.
    pub satellites: usize,
    /// Dilutions of precision of the solution's satellites (`None` under 4).
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
        Self::with_sky(cfg, sky, rng)
    }

    /// A receiver under `sky`, its errors drawn from `rng`.
    pub fn with_sky(cfg: &GnssConfig, sky: Constellation, mut rng: SimRng) -> Self {
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
    /// says whether a ray from the antenna reaches the sky that way; no reflections (a
    /// hidden satellite is lost). Epochs come in time order.
    pub fn measure(
        &mut self,
        t_ns: i64,
        antenna_enu_m: &Vector3<f64>,
        mut visible: impl FnMut(&Vector3<f64>) -> bool,
    ) -> GnssFix {
        let received: Vec<Reception> = self
            .tracked(t_ns)
            .into_iter()
            .filter(|d| visible(d))
            .map(|direction| Reception {
                direction,
                path: Path::Direct,
            })
            .collect();
        self.solve(t_ns, antenna_enu_m, &received)
    }

    /// The epoch at `t_ns` of an antenna truly at `antenna_enu_m` among surfaces that both
    /// hide and reflect satellites ([`receive`]; `cast` as there), whatever `reflections`
    /// says. Epochs come in time order.
    pub fn measure_reflecting(
        &mut self,
        t_ns: i64,
        antenna_enu_m: &Vector3<f64>,
        cast: impl FnMut(&Vector3<f64>, &Vector3<f64>, f64) -> Option<f64>,
    ) -> GnssFix {
        let received = receive(
            &self.tracked(t_ns),
            antenna_enu_m,
            self.cfg.reflection_range_m,
            cast,
        );
        self.solve(t_ns, antenna_enu_m, &received)
    }

    /// The epoch at `t_ns` of an antenna at `antenna_enu_m` among the surfaces `caster`
    /// holds: with `reflections`, [`Self::measure_reflecting`]; without,
    /// [`Self::measure`] with [`sky_visible`], as before reflections were modelled.
    pub fn measure_among(
        &mut self,
        t_ns: i64,
        antenna_enu_m: &Vector3<f64>,
        caster: &dyn RayCaster,
    ) -> GnssFix {
        if self.cfg.reflections {
            self.measure_reflecting(t_ns, antenna_enu_m, |o, d, reach| {
                first_hit(caster, o, d, reach)
            })
        } else {
            self.measure(t_ns, antenna_enu_m, |d| {
                sky_visible(caster, antenna_enu_m, d)
            })
        }
    }

    /// The fix from the satellites `received` (in the tracked order).
    fn solve(
        &mut self,
        t_ns: i64,
        antenna_enu_m: &Vector3<f64>,
        received: &[Reception],
    ) -> GnssFix {
        let all: Vec<Vector3<f64>> = received.iter().map(|r| r.direction).collect();
        let geometry = dops(&all);
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
        // The line-of-sight satellites: all of them unless some arrive by a reflection alone.
        let los: Vec<&Reception> = received
            .iter()
            .filter(|r| !matches!(r.path, Path::Nlos { .. }))
            .collect();
        let any_nlos = los.len() < received.len();
        let los_geometry = if any_nlos {
            dops(&los.iter().map(|r| r.direction).collect::<Vec<_>>())
        } else {
            geometry
        };
        let rtk_holds = |n: usize, g: Option<(f64, f64, f64)>| {
            n >= self.cfg.rtk_min_satellites
                && g.is_some_and(|(_, _, p)| p <= self.cfg.rtk_max_pdop)
        };
        let status = match (self.cfg.profile, geometry) {
            (GnssProfile::None, _) | (_, None) => {
                self.rtk_since_ns = None;
                FixStatus::None
            }
            (GnssProfile::Consumer, Some(_)) => FixStatus::Single,
            (GnssProfile::Rtk, Some(_)) => {
                // Ambiguities resolve on line-of-sight satellites; NLOS ones keep it float.
                if rtk_holds(los.len(), los_geometry) {
                    let since = *self.rtk_since_ns.get_or_insert(t_ns);
                    if (t_ns - since) as f64 * 1e-9 >= self.cfg.rtk_fix_after_s {
                        FixStatus::Fixed
                    } else {
                        FixStatus::Float
                    }
                } else {
                    self.rtk_since_ns = None;
                    if rtk_holds(received.len(), geometry) {
                        FixStatus::Float
                    } else {
                        FixStatus::Single
                    }
                }
            }
        };
        // The solution's satellites: a fix's are the line-of-sight ones.
        let (used, used_geometry): (Vec<&Reception>, _) = if status == FixStatus::Fixed {
            (los, los_geometry)
        } else {
            (received.iter().collect(), geometry)
        };
        let (hdop, vdop) = used_geometry.map_or((None, None), |(h, v, _)| (Some(h), Some(v)));
        // Reflections move the solution; a sky of direct rays alone leaves it as it was.
        let observable = match status {
            FixStatus::Single => Observable::Code,
            _ => Observable::Carrier,
        };
        let bias = if used.iter().any(|r| r.path != Path::Direct) {
            let directions: Vec<Vector3<f64>> = used.iter().map(|r| r.direction).collect();
            let biases: Vec<f64> = used
                .iter()
                .map(|r| {
                    r.range_bias_m(
                        observable,
                        self.cfg.reflection_amplitude,
                        self.cfg.correlator_spacing_chips,
                    )
                })
                .collect();
            position_error(&directions, &biases)
        } else {
            None
        };
        let (position_enu_m, variance_enu_m2) = match (self.cfg.error_model(status), slot(status)) {
            (Some(m), Some(i)) => {
                let sh = m.sigma_h_m * hdop.unwrap_or(1.0).max(1.0);
                let sv = m.sigma_v_m * vdop.unwrap_or(1.0).max(1.0);
                let u = self.states[i];
                let p = antenna_enu_m + Vector3::new(sh * u.x, sh * u.y, sv * u.z);
                (Some(bias.map_or(p, |b| p + b)), [sh * sh, sh * sh, sv * sv])
            }
            _ => (None, [0.0; 3]),
        };
        GnssFix {
            stamp_ns: t_ns,
            status,
            position_enu_m,
            variance_enu_m2,
            satellites: used.len(),
            hdop,
            vdop,
            geodetic: position_enu_m.map(|p| geodetic_from_enu(self.cfg.datum, &p)),
            latency_ns: 0,
        }
    }
}

impl GnssReceiver {
    /// The epoch at `t_ns` of the antenna at `base_from_antenna` on the robot of `scene`,
    /// among the world's mesh ([`Self::measure_among`]); and the antenna's true position.
    pub fn measure_scene(
        &mut self,
        scene: &Scene<'_>,
        t_ns: i64,
        base_from_antenna: &Isometry3<f64>,
    ) -> (GnssFix, Vector3<f64>) {
        let world_from_antenna = scene.trajectory.state(t_ns).world_from_base * base_from_antenna;
        let antenna = world_from_antenna.translation.vector;
        let fix = self.measure_among(t_ns, &antenna, scene.caster);
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

    /// FNV-1a over every field of a fix, bit for bit.
    fn digest(fixes: &[GnssFix]) -> u64 {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        let mut eat = |x: u64| {
            for b in x.to_le_bytes() {
                h ^= b as u64;
                h = h.wrapping_mul(0x0100_0000_01b3);
            }
        };
        for f in fixes {
            eat(f.stamp_ns as u64);
            eat(f.status as u64);
            eat(f.satellites as u64);
            for v in f.position_enu_m.map_or([f64::NAN; 3], |p| [p.x, p.y, p.z]) {
                eat(v.to_bits());
            }
            for v in f.variance_enu_m2 {
                eat(v.to_bits());
            }
            eat(f.hdop.map_or(u64::MAX, f64::to_bits));
            eat(f.vdop.map_or(u64::MAX, f64::to_bits));
            for v in f.geodetic.unwrap_or([f64::NAN; 3]) {
                eat(v.to_bits());
            }
            eat(f.latency_ns as u64);
        }
        h
    }

    /// A lane between two walls 1.9 m high and 120 m long along x, 1.5 m either side of it
    /// (two rows of canopy).
    fn lane_walls() -> crate::raycast::BruteForce {
        use crate::world::{Material, Mesh};
        let mut mesh = Mesh::new();
        for y in [-1.5, 1.5] {
            let v: Vec<u32> = [[-60.0, 0.0], [60.0, 0.0], [60.0, 1.9], [-60.0, 1.9]]
                .iter()
                .map(|[x, z]| mesh.push_vertex(Point3::new(*x, y, *z)))
                .collect();
            mesh.push_triangle([v[0], v[1], v[2]], Material::Leaf);
            mesh.push_triangle([v[0], v[2], v[3]], Material::Leaf);
        }
        crate::raycast::BruteForce::build(&mesh)
    }

    /// The fixes of an RTK and a consumer receiver (seed 7, `reflections` as given) driven
    /// down that lane, the antenna 0.8 m up and 0.3 m off its centre, at 0.2 m/s for 200 s,
    /// among the walls ([`GnssReceiver::measure_among`]).
    fn lane_drive(caster: &crate::raycast::BruteForce, reflections: bool) -> Vec<GnssFix> {
        let mut out = Vec::new();
        for profile in [GnssProfile::Rtk, GnssProfile::Consumer] {
            let cfg = GnssConfig {
                profile,
                reflections,
                ..GnssConfig::default()
            };
            let mut rx = GnssReceiver::new(&cfg, crate::rng::stream(7, "gnss"));
            for k in 0..1000 {
                let t_s = k as f64 / 5.0;
                let antenna = Vector3::new(-20.0 + 0.2 * t_s, 0.3, 0.8);
                out.push(rx.measure_among((t_s * 1e9) as i64, &antenna, caster));
            }
        }
        out
    }

    /// Without reflections the model's fixes are those it gave before reflections were
    /// modelled, bit for bit: [`lane_drive`]'s digest as that version computed it (on
    /// x86-64 Linux: the digest holds the platform's `sin`, `exp`, … to the last bit).
    /// With them, the same drive differs: the walls reflect.
    #[test]
    fn without_reflections_the_fixes_are_unchanged() {
        let walls = lane_walls();
        let off = lane_drive(&walls, false);
        assert_eq!(digest(&off), 0x03d5_b187_099b_06b9, "reflections off");
        let on = lane_drive(&walls, true);
        assert_ne!(digest(&on), digest(&off), "the walls reflect");
    }

    /// An antenna 1 m up beside a wall 2 m to its west (3 m high, 100 m long), under a
    /// standing sky; `east` and `west` make the sky's low satellites.
    fn beside_a_wall() -> (crate::raycast::BruteForce, Vec<Vector3<f64>>) {
        use crate::world::{Material, Mesh};
        let mut mesh = Mesh::new();
        let v: Vec<u32> = [[-50.0, 0.0], [50.0, 0.0], [50.0, 3.0], [-50.0, 3.0]]
            .iter()
            .map(|[y, z]| mesh.push_vertex(Point3::new(-2.0, *y, *z)))
            .collect();
        mesh.push_triangle([v[0], v[1], v[2]], Material::Post);
        mesh.push_triangle([v[0], v[2], v[3]], Material::Post);
        let sky = vec![
            sky_direction(270.0, 20.0), // west, low: behind the wall
            sky_direction(90.0, 30.0),  // east: its mirror ray meets the wall
            sky_direction(0.0, 60.0),
            sky_direction(180.0, 45.0),
            sky_direction(270.0, 75.0), // west, high: over the wall
            sky_direction(20.0, 35.0),
            sky_direction(160.0, 25.0),
        ];
        (crate::raycast::BruteForce::build(&mesh), sky)
    }

    /// A unit vector to the sky at this azimuth (degrees clockwise from north) and elevation.
    fn sky_direction(azimuth_deg: f64, elevation_deg: f64) -> Vector3<f64> {
        let (az, el) = (azimuth_deg.to_radians(), elevation_deg.to_radians());
        Vector3::new(el.cos() * az.sin(), el.cos() * az.cos(), el.sin())
    }

    /// The wall hides the low western satellite (nothing east of the antenna reflects it)
    /// and reflects the eastern one, still in view: multipath with the extra path of a
    /// vertical reflector 2 m away, `2·d·cos(el)`; every other satellite arrives directly
    /// (the high western one passes over the wall; the others' mirror rays miss it).
    #[test]
    fn a_wall_beside_the_antenna_hides_one_satellite_and_reflects_another() {
        let (wall, sky) = beside_a_wall();
        let antenna = Vector3::new(0.0, 0.0, 1.0);
        let got = receive(&sky, &antenna, 15.0, |o, d, r| first_hit(&wall, o, d, r));
        assert_eq!(got.len(), sky.len() - 1, "{got:?}");
        assert!(
            got.iter().all(|r| r.direction != sky[0]),
            "the west one is lost"
        );
        let east = got.iter().find(|r| r.direction == sky[1]).expect("east");
        let Path::Multipath { delay_m } = east.path else {
            panic!("{east:?}")
        };
        let expected = 2.0 * 2.0 * 30f64.to_radians().cos();
        assert!(
            (delay_m - expected).abs() < 1e-4,
            "{delay_m} m, not {expected}"
        );
        assert!(
            got.iter()
                .filter(|r| r.direction != sky[1])
                .all(|r| r.path == Path::Direct)
        );
        // Beyond the range, the same wall reflects nothing.
        let far = receive(&sky, &antenna, 2.0, |o, d, r| first_hit(&wall, o, d, r));
        assert!(far.iter().all(|r| r.path == Path::Direct), "{far:?}");
    }

    /// Two walls as a lane between rows: 1.9 m high, 1.2 m west and 1.8 m east of an
    /// antenna 0.8 m up. A satellite low in the west is hidden by the west wall; the east
    /// wall reflects it over the west one (NLOS, extra path `2 × 1.8 m × cos 20°`); the
    /// others stand high enough to be seen over both and their mirror rays pass over both.
    fn a_lane() -> (crate::raycast::BruteForce, Vec<Vector3<f64>>, Vector3<f64>) {
        use crate::world::{Material, Mesh};
        let mut mesh = Mesh::new();
        for x in [-1.2, 1.8] {
            let v: Vec<u32> = [[-50.0, 0.0], [50.0, 0.0], [50.0, 1.9], [-50.0, 1.9]]
                .iter()
                .map(|[y, z]| mesh.push_vertex(Point3::new(x, *y, *z)))
                .collect();
            mesh.push_triangle([v[0], v[1], v[2]], Material::Leaf);
            mesh.push_triangle([v[0], v[2], v[3]], Material::Leaf);
        }
        let sky = vec![
            sky_direction(270.0, 20.0), // west, low
            sky_direction(0.0, 20.0),   // along the lane, both ways
            sky_direction(180.0, 30.0),
            sky_direction(90.0, 70.0),
            sky_direction(280.0, 65.0),
            sky_direction(45.0, 40.0),
        ];
        (
            crate::raycast::BruteForce::build(&mesh),
            sky,
            Vector3::new(0.0, 0.0, 0.8),
        )
    }

    /// A receiver under a standing `sky` whose process errors are zero: its position error
    /// is the reflections' alone.
    fn exact_receiver(profile: GnssProfile, sky: &[Vector3<f64>]) -> GnssReceiver {
        let zero = ErrorModel {
            sigma_h_m: 0.0,
            sigma_v_m: 0.0,
            tau_s: 1.0,
        };
        let cfg = GnssConfig {
            profile,
            fixed: zero,
            float: zero,
            single: zero,
            consumer: zero,
            ..GnssConfig::default()
        };
        GnssReceiver::with_sky(
            &cfg,
            Constellation::standing(sky),
            crate::rng::stream(7, "gnss"),
        )
    }

    /// The least-squares position error of satellites `directions` with range biases
    /// `b`, by the pseudo-inverse of `G` (an SVD: not the normal equations the model uses).
    fn least_squares_error(directions: &[Vector3<f64>], b: &[f64]) -> Vector3<f64> {
        let g = nalgebra::DMatrix::from_fn(directions.len(), 4, |i, j| {
            if j < 3 { -directions[i][j] } else { 1.0 }
        });
        let x =
            g.pseudo_inverse(1e-12).expect("full rank") * nalgebra::DVector::from_column_slice(b);
        Vector3::new(x[0], x[1], x[2])
    }

    /// The satellite hidden behind one row and reflected off the other arrives late by the
    /// image geometry's extra path (3.38 m); a single-point fix moves by that bias through
    /// the least squares, away from the satellite (east, by over a third of it). For RTK it
    /// is the fifth satellite: float with it, never fixed (four in view), where without
    /// reflections the receiver has four and a single fix.
    #[test]
    fn a_satellite_hidden_behind_one_row_is_received_off_the_other() {
        let (lane, sky, antenna) = a_lane();
        let cast = |o: &Vector3<f64>, d: &Vector3<f64>, r: f64| first_hit(&lane, o, d, r);
        let got = receive(&sky, &antenna, 15.0, cast);
        assert_eq!(got.len(), sky.len(), "{got:?}");
        let expected = 2.0 * 1.8 * 20f64.to_radians().cos();
        match got[0].path {
            Path::Nlos { delay_m } => {
                assert!(
                    (delay_m - expected).abs() < 1e-4,
                    "{delay_m} m, not {expected}"
                )
            }
            other => panic!("west: {other:?}"),
        }
        assert!(got[1..].iter().all(|r| r.path == Path::Direct), "{got:?}");
        let mut b = vec![0.0; sky.len()];
        b[0] = expected;
        let want = least_squares_error(&sky, &b);
        // East, away from the western satellite, by decimetres to metres.
        assert!(want.x > 0.3 * expected, "{want}");

        let mut rx = exact_receiver(GnssProfile::Consumer, &sky);
        let fix = rx.measure_reflecting(0, &antenna, cast);
        assert_eq!((fix.status, fix.satellites), (FixStatus::Single, 6));
        let err = fix.position_enu_m.expect("fix") - antenna;
        assert!((err - want).norm() < 1e-4, "{err} against {want}");
        // Without reflections: five satellites and no error.
        let mut rx = exact_receiver(GnssProfile::Consumer, &sky);
        let fix = rx.measure(0, &antenna, |d| sky_visible(&lane, &antenna, d));
        assert_eq!(fix.satellites, 5);
        assert!((fix.position_enu_m.expect("fix") - antenna).norm() < 1e-12);

        // RTK with one satellite fewer in view (the one along the lane northwards gone):
        // four in view and one NLOS.
        let rtk_sky: Vec<_> = sky.iter().copied().filter(|d| *d != sky[1]).collect();
        let mut rx = exact_receiver(GnssProfile::Rtk, &rtk_sky);
        let mut plain = exact_receiver(GnssProfile::Rtk, &rtk_sky);
        for k in 0..100 {
            let t = k * 200_000_000;
            let fix = rx.measure_reflecting(t, &antenna, cast);
            assert_eq!((fix.status, fix.satellites), (FixStatus::Float, 5), "{k}");
            // Float: the NLOS carrier is late by the whole extra path too.
            let mut b = vec![0.0; rtk_sky.len()];
            b[0] = expected;
            let want = least_squares_error(&rtk_sky, &b);
            let err = fix.position_enu_m.expect("fix") - antenna;
            assert!((err - want).norm() < 1e-4, "{err} against {want}");
            let fix = plain.measure(t, &antenna, |d| sky_visible(&lane, &antenna, d));
            assert_eq!((fix.status, fix.satellites), (FixStatus::Single, 4), "{k}");
        }
    }

    /// A fixed receiver beside the wall ([`beside_a_wall`]): the multipath satellite's
    /// carrier error moves the fix by at most what `λ/4` on its range moves a least-squares
    /// solution, and by exactly what its geometry gives.
    #[test]
    fn multipath_moves_a_fix_by_its_carrier_error() {
        let (wall, sky) = beside_a_wall();
        let antenna = Vector3::new(0.0, 0.0, 1.0);
        let cast = |o: &Vector3<f64>, d: &Vector3<f64>, r: f64| first_hit(&wall, o, d, r);
        let mut rx = exact_receiver(GnssProfile::Rtk, &sky);
        let cfg = GnssConfig::default();
        let mut fix = rx.measure_reflecting(0, &antenna, cast);
        for k in 1..=60 {
            fix = rx.measure_reflecting(k * 200_000_000, &antenna, cast);
        }
        assert_eq!((fix.status, fix.satellites), (FixStatus::Fixed, 6));
        let seen: Vec<_> = sky.iter().copied().filter(|d| *d != sky[0]).collect();
        let multipath = *receive(&sky, &antenna, cfg.reflection_range_m, cast)
            .iter()
            .find(|r| r.direction == sky[1])
            .expect("east");
        let carrier = multipath.range_bias_m(
            Observable::Carrier,
            cfg.reflection_amplitude,
            cfg.correlator_spacing_chips,
        );
        let bound = L1_WAVELENGTH_M / std::f64::consts::TAU * cfg.reflection_amplitude.asin();
        assert!(carrier.abs() <= bound + 1e-12 && bound < L1_WAVELENGTH_M / 4.0);
        let b: Vec<f64> = seen
            .iter()
            .map(|d| if *d == sky[1] { carrier } else { 0.0 })
            .collect();
        let want = least_squares_error(&seen, &b);
        let err = fix.position_enu_m.expect("fix") - antenna;
        assert!((err - want).norm() < 1e-9, "{err} against {want}");
        assert!(err.norm() > 0.0);
        // A single fix there takes the code's error, larger.
        let mut rx = exact_receiver(GnssProfile::Consumer, &sky);
        let single = rx
            .measure_reflecting(0, &antenna, cast)
            .position_enu_m
            .expect("fix")
            - antenna;
        let code = multipath.range_bias_m(
            Observable::Code,
            cfg.reflection_amplitude,
            cfg.correlator_spacing_chips,
        );
        let b: Vec<f64> = seen
            .iter()
            .map(|d| if *d == sky[1] { code } else { 0.0 })
            .collect();
        assert!((single - least_squares_error(&seen, &b)).norm() < 1e-9);
        assert!(code.abs() > carrier.abs(), "code {code}, carrier {carrier}");
    }

    /// Surfaces that hide satellites but lie beyond the reflection range (here 500 m off,
    /// everywhere below 35°) reflect nothing: the receiver's fixes are bit for bit those
    /// without reflections, over a moving sky and an RTK receiver's fix and refix.
    #[test]
    fn hiding_surfaces_out_of_range_change_nothing() {
        let low = 35f64.to_radians().sin();
        let far = |_: &Vector3<f64>, d: &Vector3<f64>, reach: f64| {
            (d.z < low && reach >= 500.0).then_some(500.0)
        };
        for profile in [GnssProfile::Rtk, GnssProfile::Consumer] {
            let (mut a, mut b) = (receiver(profile), receiver(profile));
            for k in 0..3000 {
                let t = k * 200_000_000;
                let at = Vector3::new(0.01 * k as f64, 2.0, 1.7);
                let with = a.measure_reflecting(t, &at, far);
                let without = b.measure(t, &at, |d| d.z >= low);
                assert_eq!(with, without, "epoch {k}");
            }
        }
    }

    /// Near a reflector the receiver is fooled: in the lane an RTK receiver is float on the
    /// NLOS satellite (reported σ 0.2 m per axis, scaled by HDOP), and its horizontal error
    /// stays above twice that σ at every epoch of 200 s, where without reflections its
    /// single fix's error stays within four of its σ on each axis.
    #[test]
    fn near_a_reflector_the_error_exceeds_the_reported_sigma() {
        let (lane, sky, antenna) = a_lane();
        let rtk_sky: Vec<_> = sky.iter().copied().filter(|d| *d != sky[1]).collect();
        let cfg = GnssConfig {
            profile: GnssProfile::Rtk,
            ..GnssConfig::default()
        };
        let mut rx = GnssReceiver::with_sky(
            &cfg,
            Constellation::standing(&rtk_sky),
            crate::rng::stream(7, "gnss"),
        );
        let mut plain = rx.clone();
        let mut worst_ratio = f64::INFINITY;
        let mut plain_ratio: f64 = 0.0;
        for k in 0..1000 {
            let t = k * 200_000_000;
            let fix = rx.measure_among(t, &antenna, &lane);
            assert_eq!(fix.status, FixStatus::Float);
            let e = fix.position_enu_m.expect("fix") - antenna;
            worst_ratio = worst_ratio.min(e.xy().norm() / fix.variance_enu_m2[0].sqrt());
            let fix = plain.measure(t, &antenna, |d| sky_visible(&lane, &antenna, d));
            let e = fix.position_enu_m.expect("fix") - antenna;
            let s = fix.variance_enu_m2[0].sqrt();
            plain_ratio = plain_ratio.max(e.x.abs().max(e.y.abs()) / s);
        }
        assert!(worst_ratio > 2.0, "error within {worst_ratio} σ at best");
        assert!(plain_ratio < 4.0, "without reflections: {plain_ratio} σ");
    }

    /// The code loop's error against the narrow correlator's envelope (spacing 0.1 chip):
    /// `aδ/(1+a)` for short delays, `a·s/2` on the plateau, zero past `1 + s/2` chips; and
    /// for every phase the code and carrier errors of a multipath satellite stay within the
    /// envelope's in-phase and out-of-phase edges and `λ/4`.
    #[test]
    fn the_code_error_follows_the_narrow_correlator_envelope() {
        let s = 0.1;
        for a in [0.5, -0.5, 0.17, -0.17] {
            let short = 0.01;
            let got = dll_error_chips(a, short, s);
            assert!((got - a * short / (1.0 + a)).abs() < 1e-12, "{a}: {got}");
            let got = dll_error_chips(a, 0.5, s);
            assert!((got - a * s / 2.0).abs() < 1e-12, "{a}: plateau {got}");
            assert_eq!(
                dll_error_chips(a, 1.0 + s / 2.0 + 0.01, s),
                0.0,
                "{a}: long"
            );
        }
        let alpha = 0.5;
        for i in 0..200 {
            let delay_m = 3.0 + i as f64 * 0.001;
            let r = Reception {
                direction: Vector3::z(),
                path: Path::Multipath { delay_m },
            };
            let code = r.range_bias_m(Observable::Code, alpha, s);
            let carrier = r.range_bias_m(Observable::Carrier, alpha, s);
            assert!(
                code <= alpha * delay_m / (1.0 + alpha) + 1e-9
                    && code >= -alpha * delay_m / (1.0 - alpha) - 1e-9,
                "{delay_m}: code {code}"
            );
            assert!(
                carrier.abs() < L1_WAVELENGTH_M / 4.0,
                "{delay_m}: {carrier}"
            );
        }
        let nlos = Reception {
            direction: Vector3::z(),
            path: Path::Nlos { delay_m: 2.5 },
        };
        assert_eq!(nlos.range_bias_m(Observable::Code, alpha, s), 2.5);
        assert_eq!(nlos.range_bias_m(Observable::Carrier, alpha, s), 2.5);
    }

    /// The default amplitude is wood's Fresnel coefficient at L1 and normal incidence from
    /// ITU-R P.2040-1's Table 3 (`ε' = 1.99`, `σ = 0.0047·f^1.0718` S/m).
    #[test]
    fn the_default_reflection_amplitude_is_woods() {
        use nalgebra::Complex;
        let f_ghz: f64 = 1.57542;
        let sigma = 0.0047 * f_ghz.powf(1.0718);
        let eps0 = 8.854_187_817e-12;
        let eps = Complex::new(1.99, -sigma / (std::f64::consts::TAU * f_ghz * 1e9 * eps0));
        let n = eps.sqrt();
        let gamma = ((Complex::new(1.0, 0.0) - n) / (Complex::new(1.0, 0.0) + n)).norm();
        let alpha = GnssConfig::default().reflection_amplitude;
        assert!(
            (gamma - alpha).abs() < 0.005,
            "|Γ| = {gamma}, default {alpha}"
        );
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
        let cfg = GnssConfig {
            profile: GnssProfile::Rtk,
            reflection_amplitude: 1.0,
            ..GnssConfig::default()
        };
        assert!(cfg.check().expect_err("α").contains("reflection_amplitude"));
        let cfg = GnssConfig {
            profile: GnssProfile::Rtk,
            reflection_range_m: 0.0,
            ..GnssConfig::default()
        };
        assert!(
            cfg.check()
                .expect_err("range")
                .contains("reflection_range_m")
        );
    }
}
