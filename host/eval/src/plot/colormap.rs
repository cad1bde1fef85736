//! The viridis colour map (van der Walt & Smith, matplotlib 2015), perceptually uniform
//! and readable in grey scale, as a piecewise-linear fit through 9 of its samples.

use super::Rgb;

const VIRIDIS: [[f64; 3]; 9] = [
    [68.0, 1.0, 84.0],
    [71.0, 44.0, 122.0],
    [59.0, 81.0, 139.0],
    [44.0, 113.0, 142.0],
    [33.0, 144.0, 141.0],
    [39.0, 173.0, 129.0],
    [92.0, 200.0, 99.0],
    [170.0, 220.0, 50.0],
    [253.0, 231.0, 37.0],
];

/// The viridis colour at `t` in `[0, 1]` (clamped; NaN gives the low end).
pub fn viridis(t: f64) -> Rgb {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (VIRIDIS.len() - 1) as f64;
    let i = (x.floor() as usize).min(VIRIDIS.len() - 2);
    let f = x - i as f64;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    std::array::from_fn(|c| (a[c] + f * (b[c] - a[c])).round() as u8)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ends_and_clamping() {
        assert_eq!(viridis(0.0), [68, 1, 84], "expected dark purple at 0");
        assert_eq!(viridis(1.0), [253, 231, 37], "expected yellow at 1");
        assert_eq!(viridis(7.0), viridis(1.0), "expected clamping above 1");
        assert_eq!(
            viridis(0.5),
            [33, 144, 141],
            "expected the middle sample at 0.5"
        );
    }
}
