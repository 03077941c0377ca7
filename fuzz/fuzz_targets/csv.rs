#![no_main]
//! CSV trajectories (`frame,particle,x,y,z`): any bytes give a trajectory or a placed error.
use cordis_core::io::{parse_trajectory, TrajectoryFormat};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(t) = parse_trajectory("fuzz.csv", TrajectoryFormat::Csv, data) {
        assert!(t.as_flat().iter().all(|v| v.is_finite()));
    }
});
