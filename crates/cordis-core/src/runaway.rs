//! The divergence guard: how far from its start a motion may get before it counts as diverged.
//!
//! A stable CORDIS model started from a state of size `L` (m, the largest distance of a
//! position from the centre `c` of the positions' bounding box) and speeds up to `v` (m/s) stays,
//! after a time `t`, within
//!
//! ```text
//! R(t) = F · (L + (v + 2 L / dt) t + ½ |g| t²),        F = 10⁶,  L ≥ 1 m
//! ```
//!
//! of `c`: its links hold it together within its size (a link deformed by `L` and released
//! oscillates with `ω < 2/dt`, the scheme's own stability limit, so it launches a particle at
//! most at `2 L/dt`), the rest is the motion of a thrown and falling body. `F` is a safety
//! factor against everything that bound leaves out (energy fed by signals, rest lengths far
//! from the initial lengths): a model 10⁶ times beyond it has run away. The floor `L ≥ 1 m`
//! gives a still point (a one-particle scene has no size) a scale. The limit is also capped at
//! [`CAP`] = 10¹⁰⁰ m, the old absolute guard, so that squared positions and force products
//! stay finite whatever the scene's size.
//!
//! An exponential instability from 1 m growing by λ = 1.05 per step passes this bound at
//! frame 422 (`λⁿ = 10⁶ (1 + 2n)`), against 4,719 for 10¹⁰⁰ m: the costs of a runaway candidate
//! become +inf that much earlier, and a runaway output-error model (5·10⁴⁴ m on MuJoCo's
//! cable, where `R` is ~10⁸ m) is caught instead of being reported as a fit.
//!
//! Two kinds of start: the scene's own (`x(0)`, `x(-1)`, [`crate::Plan`] compiles it, so the
//! simulator uses it), and observed motion (every frame of the takes, missing markers left
//! out, [`Runaway::of_motion`]), which the identification costs and the output-error estimator
//! use, so that the guard follows the data wherever it lies. Legitimate motion is untouched: a
//! long free fall or a throw is inside `R(t)` at every time by construction.

use crate::Vec3;

/// `F` in `R(t)` (module docs): dimensionless.
pub const FACTOR: f64 = 1e6;

/// The floor of the size `L` (m).
pub const MIN_REACH: f64 = 1.0;

/// Largest limit (m), whatever the scene: positions below it keep `|x|²` finite.
pub const CAP: f64 = 1e100;

/// The divergence bound of one start (module docs): a coordinate farther than
/// [`Runaway::limit`] from [`Runaway::centre`], or not finite, has diverged.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Runaway {
    /// Centre `c` of the start's bounding box (m).
    pub centre: Vec3,
    /// Size `L` (m): the largest distance of a start position from `c`, at least
    /// [`MIN_REACH`].
    pub reach: f64,
    /// `v` (m/s): the fastest speed of the start.
    pub speed: f64,
    /// Time of one step (s): the largest of the scene's worlds.
    pub dt: f64,
    /// The smallest world's step (s), for the launch speed `2 L / dt`.
    pub min_dt: f64,
}

impl Default for Runaway {
    /// No relative bound: only [`CAP`] (and finiteness) applies.
    fn default() -> Self {
        Runaway {
            centre: Vec3::zeros(),
            reach: f64::INFINITY,
            speed: 0.0,
            dt: 0.0,
            min_dt: 0.0,
        }
    }
}

impl Runaway {
    /// The bound of a motion given as frames of positions `dt` apart (s; NaN or infinite
    /// coordinates, a missing marker, are left out; consecutive frames give speeds). Without
    /// any finite position the bound is [`Runaway::default`] (the cap only).
    pub fn of_motion<F: AsRef<[Vec3]>>(
        frames: impl IntoIterator<Item = F> + Clone,
        dt: f64,
    ) -> Self {
        let finite = |x: &Vec3| x.iter().all(|c| c.is_finite());
        let (mut lo, mut hi) = (Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY));
        for frame in frames.clone() {
            for x in frame.as_ref().iter().filter(|x| finite(x)) {
                lo = lo.inf(x);
                hi = hi.sup(x);
            }
        }
        if !finite(&lo) {
            return Runaway::default();
        }
        let centre = (lo + hi) / 2.0;
        let (mut reach, mut speed) = (MIN_REACH, 0.0_f64);
        let mut prev: Option<F> = None;
        for frame in frames {
            for (i, x) in frame.as_ref().iter().enumerate().filter(|(_, x)| finite(x)) {
                reach = reach.max((x - centre).norm());
                let before = prev.as_ref().and_then(|p| p.as_ref().get(i));
                if let Some(b) = before.filter(|b| finite(b)) {
                    speed = speed.max((x - b).norm() / dt);
                }
            }
            prev = Some(frame);
        }
        Runaway {
            centre,
            reach,
            speed,
            dt,
            min_dt: dt,
        }
    }

    /// The bound that holds for both starts: the ball around both balls, the faster speed, the
    /// longer and the shorter steps (several takes of one scene).
    pub fn merge(self, other: Runaway) -> Runaway {
        let d = (other.centre - self.centre).norm();
        let (centre, reach) =
            if !(d.is_finite() && self.reach.is_finite() && other.reach.is_finite()) {
                (self.centre, f64::INFINITY)
            } else if d + other.reach <= self.reach {
                (self.centre, self.reach)
            } else if d + self.reach <= other.reach {
                (other.centre, other.reach)
            } else {
                let r = (d + self.reach + other.reach) / 2.0;
                (
                    self.centre + (other.centre - self.centre) * ((r - self.reach) / d),
                    r,
                )
            };
        Runaway {
            centre,
            reach,
            speed: self.speed.max(other.speed),
            dt: self.dt.max(other.dt),
            min_dt: self.min_dt.min(other.min_dt),
        }
    }

    /// `R(t)` (m) after `steps` steps, under gravity of norm `g` (m/s²): at most [`CAP`], never
    /// NaN.
    #[inline]
    pub fn limit(&self, steps: usize, g: f64) -> f64 {
        let t = steps as f64 * self.dt;
        let speed = self.speed + 2.0 * self.reach / self.min_dt;
        let r = FACTOR * (self.reach + speed * t + 0.5 * g.abs() * t * t);
        // Also NaN (an infinite reach at t = 0) goes to the cap.
        if r <= CAP {
            r
        } else {
            CAP
        }
    }

    /// Whether every coordinate of `x` is finite and within `limit` (m) of the centre.
    #[inline(always)]
    pub fn within(&self, x: &Vec3, limit: f64) -> bool {
        (x - self.centre).iter().all(|c| c.abs() <= limit)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bound_grows_with_time_speed_and_gravity_from_the_size_of_the_start() {
        let a = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(4.0, 0.0, 0.0)];
        let b = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(4.0, 0.3, 0.0)];
        let r = Runaway::of_motion([&a[..], &b[..]], 0.1);
        assert_eq!(r.centre, Vec3::new(2.0, 0.15, 0.0));
        approx::assert_relative_eq!(r.reach, (4.0_f64 + 0.0225).sqrt(), max_relative = 1e-15);
        approx::assert_relative_eq!(r.speed, 3.0, max_relative = 1e-15);
        assert_eq!(r.limit(0, 9.81), FACTOR * r.reach);
        let t = 10.0 * 0.1;
        let v = 3.0 + 2.0 * r.reach / 0.1;
        let want = FACTOR * (r.reach + v * t + 0.5 * 9.81 * t * t);
        approx::assert_relative_eq!(r.limit(10, -9.81), want, max_relative = 1e-15);
    }

    #[test]
    fn missing_markers_are_left_out_and_a_still_point_has_the_floor() {
        let a = [Vec3::new(5.0, 5.0, 5.0), Vec3::new(f64::NAN, 0.0, 0.0)];
        let r = Runaway::of_motion([&a[..]], 0.01);
        assert_eq!((r.centre, r.reach), (Vec3::new(5.0, 5.0, 5.0), MIN_REACH));
        assert!(r.within(&Vec3::new(5.0 + 0.9e6, 5.0, 5.0), r.limit(0, 0.0)));
        assert!(!r.within(&Vec3::new(5.0 + 1.1e6, 5.0, 5.0), r.limit(0, 0.0)));
        let none = Runaway::of_motion([&a[1..]], 0.01);
        assert_eq!(none, Runaway::default());
    }

    #[test]
    fn two_takes_merge_into_the_ball_around_both() {
        let a = Runaway::of_motion([[Vec3::new(-1.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0)]], 0.1);
        let b = Runaway::of_motion([[Vec3::new(9.0, 0.0, 0.0), Vec3::new(11.0, 0.0, 0.0)]], 0.2);
        let m = a.merge(b);
        assert_eq!((m.centre, m.reach), (Vec3::new(5.0, 0.0, 0.0), 6.0));
        assert_eq!((m.dt, m.min_dt), (0.2, 0.1));
        assert_eq!(a.merge(a), a);
    }

    #[test]
    fn the_limit_is_capped_and_never_lets_a_non_finite_position_through() {
        let r = Runaway {
            reach: 1e99,
            ..Runaway::of_motion([[Vec3::zeros()]], 1.0)
        };
        assert_eq!(r.limit(5, 0.0), CAP);
        assert_eq!(Runaway::default().limit(3, f64::NAN), CAP);
        for bad in [f64::NAN, f64::INFINITY, -f64::INFINITY, 2e100] {
            assert!(
                !r.within(&Vec3::new(0.0, bad, 0.0), r.limit(5, 0.0)),
                "{bad}"
            );
        }
    }
}
