//! CPU seconds of this process, for benchmarks on shared machines: the wall clock measures the
//! neighbours too (measured: a `cordis bench noise` grid took 49 min of wall time for 7.8 min of
//! CPU while other builds ran).

/// User + system CPU seconds of this process since it started, read from `/proc/self/stat`
/// (NaN where there is no such file).
pub fn process_cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return f64::NAN;
    };
    // Fields after the command name (which may hold spaces): utime and stime are 14 and 15,
    // in clock ticks (100 per second on Linux).
    let rest = stat.rsplit(')').next().unwrap_or("");
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |k: usize| {
        f.get(k)
            .and_then(|v| v.parse::<f64>().ok())
            .unwrap_or(f64::NAN)
    };
    (ticks(11) + ticks(12)) / 100.0
}

#[cfg(test)]
mod tests {
    #[test]
    fn cpu_time_grows_with_work_and_is_not_negative() {
        let a = super::process_cpu_seconds();
        let mut x = 0.0f64;
        for k in 0..30_000_000u64 {
            x += (k as f64).sqrt();
        }
        assert!(x > 0.0);
        let b = super::process_cpu_seconds();
        assert!(a >= 0.0 && b >= a, "{a} {b}");
    }
}
