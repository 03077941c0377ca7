#![no_main]
//! The thesis' `NAME.mas` (masses, then link families).
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = cordis_core::thesis::parse_mas("fuzz.mas", &String::from_utf8_lossy(data));
});
