//! Sensor effects on the rendered frame: the depth range window, edge dropout, axial depth
//! noise of a Kinect v2 and Gaussian colour noise.
//!
//! Axial noise follows Fankhauser et al. 2015, "Kinect v2 for mobile robot navigation:
//! evaluation and modeling" (ICAR), fitted on a planar target:
//! `σ_z(z, θ) = 1.5 − 0.5 z + 0.3 z² + 0.1 z^(3/2) θ² / (π/2 − θ)²` mm, z in m, θ the angle
//! between the ray and the surface normal (clamped here at 80°, beyond which the fit
//! explodes). At θ = 0: 1.3 mm at 1 m, 2.7 mm at 3 m, 5.3 mm at 4.5 m.
//!
//! Random numbers: a frame draws one 64-bit seed; each pixel then hashes (seed, index) with
//! SplitMix64, twice: one hash gives its depth noise (Irwin-Hall sum of four uniforms scaled
//! to unit variance, a Gaussian to within its tails at ±3.46σ), the other the three colour
//! channels' noise (sums of two uniforms: triangular, unit variance). Counter-based, so
//! bands run in parallel and the result never depends on the thread count.

/// Largest incidence angle the noise model is evaluated at.
const MAX_THETA_RAD: f32 = 80.0 * std::f32::consts::PI / 180.0;

/// Axial (along the optical axis) depth noise σ in metres at depth `z_m` and incidence
/// angle `theta_rad`.
pub fn axial_sigma_m(z_m: f32, theta_rad: f32) -> f32 {
    let th = theta_rad.clamp(0.0, MAX_THETA_RAD);
    let a = th * th / (std::f32::consts::FRAC_PI_2 - th).powi(2);
    let mm = 1.5 - 0.5 * z_m + 0.3 * z_m * z_m + 0.1 * z_m.powf(1.5) * a;
    mm * 1e-3
}

/// The angle term `θ² / (π/2 − θ)²` tabulated over cos θ in [0, 1] (acos per pixel costs
/// more than the rest of the noise).
fn angle_term_table() -> &'static [f32; 257] {
    static TABLE: std::sync::OnceLock<[f32; 257]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        std::array::from_fn(|k| {
            let th = (k as f32 / 256.0).acos().min(MAX_THETA_RAD);
            th * th / (std::f32::consts::FRAC_PI_2 - th).powi(2)
        })
    })
}

/// [`axial_sigma_m`] from the cosine of the incidence angle, by [`angle_term_table`].
fn sigma_from_cos(table: &[f32; 257], z: f32, cos: f32) -> f32 {
    let x = cos.clamp(0.0, 1.0) * 256.0;
    let k = (x as usize).min(255);
    let f = x - k as f32;
    let a = table[k] + (table[k + 1] - table[k]) * f;
    (1.5 - 0.5 * z + 0.3 * z * z + 0.1 * z * z.sqrt() * a) * 1e-3
}

#[derive(Debug, Clone, Copy)]
pub(crate) struct Effects<'a> {
    pub width: usize,
    pub min_depth_m: f32,
    pub max_depth_m: f32,
    pub depth_noise: bool,
    pub edge_dropout_ratio: f32,
    /// The colour noise in levels by the sum of its two 10-bit uniforms (see
    /// [`rgb_noise_table`]); empty: no colour noise.
    pub rgb_noise: &'a [f32],
    pub seed: u64,
}

/// `rgb_sigma` times [`triangular`] noise, for every sum `a + b` of its two 10-bit
/// uniforms (0..=2046): one load per channel instead of the arithmetic, same values.
pub(crate) fn rgb_noise_table(rgb_sigma: f32) -> Vec<f32> {
    (0..2047u64)
        .map(|sum| {
            // Any two uniforms with this sum: `triangular` sees only the sum (exact in f32).
            let a = sum.min(1023);
            rgb_sigma * triangular(a | (sum - a) << 10)
        })
        .collect()
}

fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A unit Gaussian (Irwin-Hall, n = 4) from counter `k` under `seed`.
fn gaussian(seed: u64, k: u64) -> f32 {
    let h = splitmix64(seed ^ k.wrapping_mul(0xd6e8_feb8_6659_fd93));
    let sum: u32 = (0..4).map(|i| ((h >> (16 * i)) & 0xffff) as u32).sum();
    // Four uniforms in [0, 1): mean 2, variance 1/3.
    (sum as f32 / 65536.0 - 2.0) * 3.0f32.sqrt()
}

/// Zero-mean, unit-variance triangular noise (sum of two uniforms) from the low 20 bits.
fn triangular(bits: u64) -> f32 {
    let a = (bits & 0x3ff) as f32;
    let b = ((bits >> 10) & 0x3ff) as f32;
    // Two uniforms in [0, 1): mean 1, variance 1/6.
    ((a + b) / 1024.0 - 1.0) * 6.0f32.sqrt()
}

impl Effects<'_> {
    /// A row of pixels `first..` of colour: linear RGB encoded with gamma 2 (the shader's
    /// albedos are decoded with the same), plus noise, three bytes a pixel. `linear` is
    /// overwritten: the encoding is done in place, in three passes over the row.
    pub fn colour_row(&self, first: usize, linear: &mut [[f32; 3]], out: &mut [u8]) {
        for c in linear.as_flattened_mut() {
            *c = c.max(0.0).sqrt() * 255.0;
        }
        self.noise_and_quantize_row(first, linear, out);
    }

    /// The second half of [`Self::colour_row`]: a row of pixels `first..` already encoded
    /// (0-255 as floats) gets its noise and becomes bytes. `encoded` is overwritten.
    pub fn noise_and_quantize_row(&self, first: usize, encoded: &mut [[f32; 3]], out: &mut [u8]) {
        if !self.rgb_noise.is_empty() {
            let noise = &self.rgb_noise[..2047];
            for (i, c) in (first..).zip(encoded.iter_mut()) {
                let bits =
                    splitmix64(self.seed ^ (2 * i as u64).wrapping_mul(0xd6e8_feb8_6659_fd93));
                for (ch, c) in c.iter_mut().enumerate() {
                    // The two 10-bit uniforms of `triangular(bits >> (20 * ch))`, summed.
                    let b = bits >> (20 * ch);
                    *c += noise[((b & 0x3ff) + ((b >> 10) & 0x3ff)) as usize];
                }
            }
        }
        for (out, &c) in out.iter_mut().zip(encoded.as_flattened()) {
            // In [0.5, 255.5]: the conversion through i32 is exact and cheaper.
            *out = ((c.clamp(0.0, 255.0) + 0.5) as i32) as u8;
        }
    }

    /// Fills one band (pixels `first..`, whole rows) of the depth image from the whole
    /// clean depth.
    pub fn depth_band(&self, first: usize, depth: &[f32], cos_incidence: &[f32], out: &mut [f32]) {
        let w = self.width;
        let n = depth.len();
        let table = angle_term_table();
        // Row by row: no integer division per pixel.
        for (r, out) in out.chunks_mut(w).enumerate() {
            let row = first + r * w;
            for (u, out) in out.iter_mut().enumerate() {
                let i = row + u;
                *out = self.depth_pixel(table, i, u, depth, cos_incidence, n);
            }
        }
    }

    #[inline]
    fn depth_pixel(
        &self,
        table: &[f32; 257],
        i: usize,
        u: usize,
        depth: &[f32],
        cos_incidence: &[f32],
        n: usize,
    ) -> f32 {
        let w = self.width;
        let z = depth[i];
        if !(self.min_depth_m..=self.max_depth_m).contains(&z) {
            return 0.0;
        }
        if self.edge_dropout_ratio > 0.0 {
            let limit = self.edge_dropout_ratio * z;
            let jump = |j: usize| {
                let nz = depth[j];
                nz == 0.0 || (nz - z).abs() > limit
            };
            if (u > 0 && jump(i - 1))
                || (u + 1 < w && jump(i + 1))
                || (i >= w && jump(i - w))
                || (i + w < n && jump(i + w))
            {
                return 0.0;
            }
        }
        if self.depth_noise {
            z + sigma_from_cos(table, z, cos_incidence[i]) * gaussian(self.seed, 2 * i as u64 + 1)
        } else {
            z
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn model_matches_the_published_fit_and_the_table() {
        // Fankhauser et al. 2015 at normal incidence: 1.5 - 0.5 z + 0.3 z^2 mm.
        for (z, mm) in [(1.0, 1.3), (3.0, 2.7), (4.5, 5.325)] {
            let got = axial_sigma_m(z, 0.0) * 1e3;
            assert!(
                (got - mm).abs() < 1e-4,
                "expected {mm} mm at {z} m, got {got}"
            );
        }
        for cos in [1.0f32, 0.9, 0.5, 0.2] {
            let (z, exact) = (3.0, axial_sigma_m(3.0, cos.acos()));
            let tabled = sigma_from_cos(angle_term_table(), z, cos);
            assert!(
                (tabled / exact - 1.0).abs() < 0.01,
                "expected the table within 1 % of the formula at cos {cos}: {tabled} vs {exact}"
            );
        }
    }

    #[test]
    fn noise_draws_have_unit_variance_and_zero_mean() {
        let n = 200_000u64;
        let (mut s, mut s2, mut t, mut t2) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        for k in 0..n {
            let g = f64::from(gaussian(42, k));
            let r = f64::from(triangular(splitmix64(k)));
            s += g;
            s2 += g * g;
            t += r;
            t2 += r * r;
        }
        let nf = n as f64;
        for (name, mean, var) in [
            ("gaussian", s / nf, s2 / nf),
            ("triangular", t / nf, t2 / nf),
        ] {
            assert!(mean.abs() < 0.01, "expected {name} mean 0, got {mean}");
            assert!(
                (var - 1.0).abs() < 0.02,
                "expected {name} variance 1, got {var}"
            );
        }
    }
}
