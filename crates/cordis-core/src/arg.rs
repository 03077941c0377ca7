//! Numbers given as arguments — command-line options, Python keywords, `Param.gene` keys —
//! checked in one place, so that the CLI and Python refuse the same values with the same
//! message: finite, in range, the unit named; and sizes checked against the machine's memory
//! before anything is allocated (a failed allocation aborts the process, and the Python
//! interpreter with it).

use crate::error::{CordisError, Result};

/// The lower end of an argument's range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Low {
    /// Strictly above this value.
    Above(f64),
    /// At or above this value.
    AtLeast(f64),
}

/// `value` if it is finite, above `low` and at most `high` (`f64::MAX`: no upper end); else a [`CordisError::Argument`]
/// at `place` (`--width`) saying the range, in `unit` (`"m"`, `"s"`, or what the number is:
/// `"the ratio max/min"`), and the value given.
pub fn number(place: &str, value: f64, low: Low, high: f64, unit: &str) -> Result<f64> {
    let inside = match low {
        Low::Above(l) => value > l,
        Low::AtLeast(l) => value >= l,
    } && value <= high
        && value.is_finite();
    if inside {
        return Ok(value);
    }
    let low = match low {
        Low::Above(l) => format!("above {}", short(l)),
        Low::AtLeast(l) => format!("at least {}", short(l)),
    };
    let high = if high == f64::MAX {
        String::new()
    } else {
        format!(" and at most {}", short(high))
    };
    Err(CordisError::argument(
        place,
        format!(
            "must be a finite number {low}{high} ({unit}), got {}",
            short(value)
        ),
    ))
}

/// The range of a marker's weight (1/σ relative): far inside f64 once squared and multiplied
/// by squared residuals, so that a weight's common scale never changes the estimate (at 1e150
/// the squares overflowed and the fit went elsewhere; a 1e±30 scale gives the estimate of 1
/// to 1e-13).
pub const WEIGHT_RANGE: (f64, f64) = (1e-30, 1e30);

/// The first of `weights` that is not a positive finite number within [`WEIGHT_RANGE`]: its
/// index and why, for `place[k]: why`. The CLI, Python and the report refuse the same.
pub fn bad_weight(weights: &[f64]) -> Option<(usize, String)> {
    let (low, high) = WEIGHT_RANGE;
    let k = weights.iter().position(|w| !(*w >= low && *w <= high))?;
    let w = weights[k];
    Some((
        k,
        match w.is_finite() && w > 0.0 {
            true => format!(
                "{w:e} is outside [{low:e}, {high:e}]: weights are relative (1/σ), scale them all \
                 by one factor into it (a common scale does not change the estimate)"
            ),
            false => format!("must be a positive finite number (1/σ relative), got {w:?}"),
        },
    ))
}

/// A noise level (added or assumed) larger than this many times the size of the scene and
/// its motion is a wrong unit, not an experiment: the motion is lost in it (identify's
/// `noise` at 1e300 m met overflowing numbers, discover's answered "no particle moves").
pub const NOISE_MAX_SIZES: f64 = 10.0;

/// Why `noise` (m) is refused against the size (m) of `what` it is added to or read from:
/// more than [`NOISE_MAX_SIZES`] times it. `None` when it is within (or nothing has a size).
pub fn noise_out_of_scale(noise: f64, size: f64, what: &str) -> Option<String> {
    let most = NOISE_MAX_SIZES;
    (size.is_finite() && size > 0.0 && noise > most * size).then(|| {
        format!(
            "{noise:e} m is more than {most} times the size of {what} ({size:.3e} m): a \
             standard deviation in m"
        )
    })
}

/// A number as a reader wants it: plain between 1e-4 and 1e6, else in scientific notation
/// (`1e100`, not the 101 digits `Display` writes).
pub fn short(x: f64) -> String {
    if x == 0.0 || !x.is_finite() || (1e-4..1e6).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// The width of the unknown boxes that `--unknowns` / `example(unknowns=True)` write: the
/// ratio max/min, above 1 (a box of width 1 or less holds only the truth, or nothing) and at
/// most 1e100 (beyond, the bounds of a parameter of ordinary size leave the finite numbers).
pub fn box_width(place: &str, width: f64) -> Result<f64> {
    number(
        place,
        width,
        Low::Above(1.0),
        1e100,
        "the boxes' ratio max/min",
    )
}

/// Refuses, before allocating, `bytes` that the machine's memory cannot hold: more than the
/// memory available now (Linux `MemAvailable`, swap not counted) or, where that is not known,
/// than an allocation may ask for. `what` says what needs them, `place` names the argument
/// that set the size (`--frames`); the message gives the estimate and the memory.
pub fn fits_in_memory(place: &str, bytes: f64, what: &str) -> Result<()> {
    let (limit, of) = match available_memory() {
        Some(m) => (m as f64, "of memory available"),
        None => (isize::MAX as f64, "that one allocation may take"),
    };
    if bytes.is_finite() && bytes <= limit {
        return Ok(());
    }
    Err(CordisError::argument(
        place,
        format!("{what} needs {bytes:.3e} bytes, more than the {limit:.3e} bytes {of}"),
    ))
}

/// Bytes of memory available for new allocations (Linux `/proc/meminfo`), when known.
pub fn available_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kb.checked_mul(1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn number_refuses_non_finite_and_out_of_range_values_naming_the_unit() {
        assert_eq!(number("--x", 2.0, Low::Above(1.0), 10.0, "m").unwrap(), 2.0);
        assert_eq!(
            number("--x", 0.0, Low::AtLeast(0.0), 1.0, "m").unwrap(),
            0.0
        );
        for bad in [
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            1.0,
            0.5,
            11.0,
            -0.0,
        ] {
            let e = number("--x", bad, Low::Above(1.0), 10.0, "m").unwrap_err();
            let text = e.to_string();
            assert!(matches!(e, CordisError::Argument { .. }), "{text}");
            assert!(
                text.starts_with("--x: must be a finite number above 1 and at most 10 (m), got "),
                "{text}"
            );
        }
    }

    #[test]
    fn fits_in_memory_refuses_more_than_the_machine_has() {
        assert!(fits_in_memory("--n", 1e3, "a table").is_ok());
        let e = fits_in_memory("--n", 1e30, "a table")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("--n: a table needs 1.000e30 bytes, more than the"),
            "{e}"
        );
        assert!(fits_in_memory("--n", f64::NAN, "a table").is_err());
        assert_eq!(short(1e100), "1e100");
        assert_eq!(short(0.5), "0.5");
        assert_eq!(short(-2.5e-7), "-2.5e-7");
    }
}
