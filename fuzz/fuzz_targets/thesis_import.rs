#![no_main]
//! `cordis import NAME`: the input is split at 0xFF bytes into NAME.mas, NAME.cat, NAME.ini,
//! NAME.tra, NAME.lock and Param.gene (a missing part is a missing file), written to a fresh
//! directory and imported; the assembled scene is then simulated for a few frames, as the
//! user's next command would.
use libfuzzer_sys::fuzz_target;

const FILES: [&str; 6] = ["m.mas", "m.cat", "m.ini", "m.tra", "m.lock", "Param.gene"];

fuzz_target!(|data: &[u8]| {
    let dir = tempfile::tempdir().expect("temporary directory");
    for (part, name) in data.split(|&b| b == 0xFF).zip(FILES) {
        std::fs::write(dir.path().join(name), part).expect("write");
    }
    if let Ok(model) = cordis_core::thesis::import(&dir.path().join("m"), 0.01) {
        let _ = model.scene.simulate(4);
    }
});
