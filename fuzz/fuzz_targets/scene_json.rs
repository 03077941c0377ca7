#![no_main]
//! JSON scenes, then what `cordis simulate` does with them: compile, and simulate a few frames.
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    if let Ok(scene) = cordis_core::Scene::from_json_str(text) {
        if let Ok(t) = scene.simulate(8) {
            assert!(t.as_flat().iter().all(|v| v.is_finite()));
        }
    }
});
