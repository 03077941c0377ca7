#![no_main]
//! The thesis' `NAME.lock`.
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = cordis_core::thesis::parse_lock("fuzz.lock", &String::from_utf8_lossy(data));
});
