#![no_main]
//! JSON scenes, then what `cordis check` and `cordis simulate` do with them: the stability
//! report, the largest stable step, and a few frames (no NaN may come out).
use cordis_core::stability::{max_stable_dt, stability};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(scene) = cordis_core::Scene::from_json_str(text) else { return };
    let r = stability(&scene).expect("a scene that parsed is valid");
    assert!(!r.max_ratio.is_nan() && !r.local_max_ratio.is_nan());
    assert!(r.per_particle.iter().flatten().all(|q| !q.is_nan()));
    if let Some(dt) = max_stable_dt(&scene).expect("valid") {
        assert!(dt > 0.0 && !dt.is_nan());
    }
    if let Ok(t) = scene.simulate(8) {
        assert!(t.as_flat().iter().all(|v| v.is_finite()));
    }
});
