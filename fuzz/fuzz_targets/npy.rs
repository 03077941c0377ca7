#![no_main]
//! NumPy `.npy` trajectories: a crafted header must not allocate beyond the data it carries.
use cordis_core::io::{parse_trajectory, TrajectoryFormat};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(t) = parse_trajectory("fuzz.npy", TrajectoryFormat::Npy, data) {
        assert!(t.as_flat().iter().all(|v| v.is_finite()));
        assert_eq!(t.as_flat().len(), t.frames() * t.particles() * 3);
    }
});
