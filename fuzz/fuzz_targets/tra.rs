#![no_main]
//! The thesis' `.tra` trajectories: huge announced counts must not allocate or hang.
use cordis_core::io::{parse_trajectory, TrajectoryFormat};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(t) = parse_trajectory("fuzz.tra", TrajectoryFormat::Tra, data) {
        assert!(t.as_flat().iter().all(|v| v.is_finite()));
    }
});
