#![no_main]
//! The thesis' `NAME.ini`; the first byte picks the particle count the `.mas` would give
//! (0…255, or 2^40 when it is 255, to check that a large count allocates nothing up front).
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&n, rest)) = data.split_first() else { return };
    let n = if n == 255 { 1usize << 40 } else { n as usize };
    if let Ok(v) = cordis_core::thesis::parse_ini("fuzz.ini", &String::from_utf8_lossy(rest), n) {
        assert_eq!(v.len(), n);
    }
});
