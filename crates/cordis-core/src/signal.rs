//! Command signals (SPEC §2.5, thesis §5.1): known periodic functions of the main world's time
//! that drive TGR tendons. They are inputs, never identified.
//!
//! A signal is `offset + amplitude · shape(frac(t / period + phase))` with a normalised shape
//! in [-1, 1]:
//!
//! - `sine`: `sin(2π u)` (0 at u = 0, rising);
//! - `sawtooth` with rise fraction r: rises linearly from -1 to +1 over `u ∈ [0, r)`, then falls
//!   back linearly to -1 over `[r, 1)`. Asymmetric unless r = ½; the thesis' tadpole needs the
//!   asymmetry to travel (a symmetric signal only makes it oscillate in place, §5.1);
//! - `triangle`: the sawtooth with r = ½.

/// Normalised shape of a [`Signal`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum Shape {
    Sine,
    Triangle,
    Sawtooth,
}

impl Shape {
    pub const ALL: [Shape; 3] = [Shape::Sine, Shape::Triangle, Shape::Sawtooth];

    /// The name used in scene files.
    pub fn name(self) -> &'static str {
        match self {
            Shape::Sine => "sine",
            Shape::Triangle => "triangle",
            Shape::Sawtooth => "sawtooth",
        }
    }

    pub fn from_name(name: &str) -> Option<Shape> {
        Self::ALL.into_iter().find(|s| s.name() == name)
    }
}

/// Default rise fraction of a sawtooth (slow rise, fast fall).
pub const DEFAULT_RISE: f64 = 0.9;

/// A named periodic command signal.
#[derive(Clone, Debug, PartialEq)]
pub struct Signal {
    pub name: String,
    pub shape: Shape,
    /// Multiplies the normalised shape; in the unit of what the signal drives (N for a tendon).
    pub amplitude: f64,
    /// Period in s (> 0).
    pub period: f64,
    /// Phase as a fraction of a period (shifts the signal earlier by `phase · period`).
    pub phase: f64,
    /// Sawtooth only: fraction of the period spent rising, in (0, 1).
    pub rise: f64,
    /// Added to the scaled shape, same unit as `amplitude`.
    pub offset: f64,
}

impl Signal {
    /// A signal with phase 0, offset 0 and the default rise.
    pub fn new(name: impl Into<String>, shape: Shape, amplitude: f64, period: f64) -> Self {
        Signal {
            name: name.into(),
            shape,
            amplitude,
            period,
            phase: 0.0,
            rise: if shape == Shape::Triangle {
                0.5
            } else {
                DEFAULT_RISE
            },
            offset: 0.0,
        }
    }

    /// Sets the rise fraction (builder style; sawtooth only, see [`Shape`]).
    pub fn with_rise(mut self, rise: f64) -> Self {
        self.rise = rise;
        self
    }

    pub fn with_phase(mut self, phase: f64) -> Self {
        self.phase = phase;
        self
    }

    pub fn with_offset(mut self, offset: f64) -> Self {
        self.offset = offset;
        self
    }

    /// The normalised shape in [-1, 1] at time `t` (s).
    #[inline]
    pub fn unit(&self, t: f64) -> f64 {
        let c = t / self.period + self.phase;
        // The fraction of the period in [0, 1): `c - floor(c)` (also right for negative t).
        let u = c - c.floor();
        match self.shape {
            Shape::Sine => (std::f64::consts::TAU * u).sin(),
            Shape::Triangle => ramp(u, 0.5),
            Shape::Sawtooth => ramp(u, self.rise),
        }
    }

    /// The signal's value at time `t` (s).
    #[inline]
    pub fn value(&self, t: f64) -> f64 {
        self.offset + self.amplitude * self.unit(t)
    }
}

/// -1 → +1 linearly over `[0, r)`, then +1 → -1 over `[r, 1)`.
#[inline]
fn ramp(u: f64, r: f64) -> f64 {
    if u < r {
        -1.0 + 2.0 * u / r
    } else {
        1.0 - 2.0 * (u - r) / (1.0 - r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sampled(s: &Signal, n: usize) -> Vec<f64> {
        (0..n)
            .map(|k| s.value(k as f64 * s.period / n as f64))
            .collect()
    }

    #[test]
    fn sine_has_its_quarter_values_amplitude_and_offset() {
        let s = Signal::new("s", Shape::Sine, 2.0, 4.0).with_offset(0.5);
        let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
        assert!(close(s.value(0.0), 0.5));
        assert!(close(s.value(1.0), 2.5));
        assert!(close(s.value(2.0), 0.5));
        assert!(close(s.value(3.0), -1.5));
        assert!(close(s.value(4.0), 0.5), "periodic");
        assert!(close(s.value(-1.0), -1.5), "periodic backwards too");
    }

    #[test]
    fn sawtooth_rises_slowly_then_falls_fast() {
        let s = Signal::new("s", Shape::Sawtooth, 1.0, 1.0).with_rise(0.8);
        let v = sampled(&s, 1000);
        // Extremes at u = 0 (-1) and u = r (+1).
        assert!((v[0] + 1.0).abs() < 1e-12);
        assert!((v[800] - 1.0).abs() < 1e-12);
        let max = v.iter().cloned().fold(f64::MIN, f64::max);
        let min = v.iter().cloned().fold(f64::MAX, f64::min);
        assert!(max <= 1.0 + 1e-12 && min >= -1.0 - 1e-12);
        // Slopes: +2/r on the rise, -2/(1-r) on the fall (per unit of u).
        let du = 1e-3;
        assert!(((v[401] - v[400]) / du - 2.0 / 0.8).abs() < 1e-9);
        assert!(((v[901] - v[900]) / du + 2.0 / 0.2).abs() < 1e-9);
        // Mean over a period is 0 (two triangles of opposite signs).
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        assert!(mean.abs() < 1e-2, "mean {mean}");
    }

    #[test]
    fn triangle_is_the_symmetric_sawtooth() {
        let t = Signal::new("t", Shape::Triangle, 3.0, 2.0);
        let s = Signal::new("s", Shape::Sawtooth, 3.0, 2.0).with_rise(0.5);
        for k in 0..97 {
            let x = k as f64 * 0.0537;
            assert_eq!(t.value(x), s.value(x));
        }
        // Symmetric about its peak: v(P/2 - τ) = v(P/2 + τ).
        for k in 1..20 {
            let tau = k as f64 * 0.031;
            assert!((t.value(1.0 - tau) - t.value(1.0 + tau)).abs() < 1e-12);
        }
        // A triangle ignores `rise`: its shape is fixed.
        let odd = t.clone().with_rise(0.9);
        assert_eq!(odd.value(0.3), t.value(0.3));
    }

    #[test]
    fn phase_shifts_earlier_by_a_fraction_of_the_period() {
        let s = Signal::new("s", Shape::Sawtooth, 1.0, 2.0).with_rise(0.7);
        let shifted = s.clone().with_phase(0.25);
        for k in 0..50 {
            let t = k as f64 * 0.077;
            assert!((shifted.value(t) - s.value(t + 0.5)).abs() < 1e-12);
        }
    }

    #[test]
    fn names_round_trip() {
        for s in Shape::ALL {
            assert_eq!(Shape::from_name(s.name()), Some(s));
        }
        assert_eq!(Shape::from_name("square"), None);
    }
}
