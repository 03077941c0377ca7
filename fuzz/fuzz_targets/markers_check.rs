//! The property every marker-reader target checks (`#[path]`-included by `markers_*.rs`): any
//! bytes give observations — finite or NaN (missing), one label per marker, a positive finite
//! dt if any — or an error.
use cordis_core::io::{markers::parse_markers, InputFormat, ReadOptions};

pub fn check(format: InputFormat, name: &str, data: &[u8]) {
    if let Ok(m) = parse_markers(name, format, data, &ReadOptions::default()) {
        let obs = &m.observations;
        assert_eq!(obs.as_flat().len(), obs.frames() * obs.particles() * 3);
        assert!(obs.as_flat().iter().all(|v| v.is_finite() || v.is_nan()));
        assert!(obs.dt.is_none_or(|dt| dt.is_finite() && dt > 0.0));
        assert_eq!(m.labels.len(), obs.particles());
    }
}
