#![no_main]
//! The thesis' `NAME.cat` / `NAME.sav` catalogues.
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = cordis_core::thesis::parse_cat("fuzz.cat", &String::from_utf8_lossy(data));
});
