//! Axis-aligned world bounds of a picture.

/// An axis-aligned rectangle in world coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    /// Smallest x and y.
    pub min: (f64, f64),
    /// Largest x and y.
    pub max: (f64, f64),
}

impl Bounds {
    /// The rectangle between two corners (in any order).
    pub fn new(a: (f64, f64), b: (f64, f64)) -> Self {
        Self {
            min: (a.0.min(b.0), a.1.min(b.1)),
            max: (a.0.max(b.0), a.1.max(b.1)),
        }
    }

    /// The smallest rectangle around the finite `points`, grown by `margin` on every
    /// side; `None` if there is no finite point.
    pub fn around(points: impl IntoIterator<Item = (f64, f64)>, margin: f64) -> Option<Self> {
        let mut bounds: Option<Self> = None;
        for p in points
            .into_iter()
            .filter(|p| p.0.is_finite() && p.1.is_finite())
        {
            bounds = Some(match bounds {
                None => Self { min: p, max: p },
                Some(b) => Self::new(
                    (b.min.0.min(p.0), b.min.1.min(p.1)),
                    (b.max.0.max(p.0), b.max.1.max(p.1)),
                ),
            });
        }
        bounds.map(|b| Self {
            min: (b.min.0 - margin, b.min.1 - margin),
            max: (b.max.0 + margin, b.max.1 + margin),
        })
    }

    /// Extent along x.
    pub fn width(&self) -> f64 {
        self.max.0 - self.min.0
    }

    /// Extent along y.
    pub fn height(&self) -> f64 {
        self.max.1 - self.min.1
    }
}
