//! The memory check before work (docs/architecture.md §Extremes): byte sizes with units as
//! `--max-memory` takes them, the default share of the machine's free memory, and the refusal
//! of a training run whose estimated peak exceeds the limit.

use crate::error::{Result, refuse};

/// Share of the available memory a job may plan to use by default.
pub const DEFAULT_SHARE: f64 = 0.6;

/// Assumed available memory when /proc/meminfo cannot be read.
pub const FALLBACK_AVAILABLE: u64 = 4 << 30;

/// Parses a byte size: a number with an optional unit, `B`, decimal `kB`/`MB`/`GB`/`TB`
/// (powers of 1000) or binary `KiB`/`MiB`/`GiB`/`TiB` and the shorthands `K`/`M`/`G`/`T`
/// (powers of 1024); case-insensitive, a space between number and unit allowed.
pub fn parse_bytes(text: &str) -> Result<u64> {
    let t = text.trim();
    let split = t.find(|c: char| !(c.is_ascii_digit() || c == '.')).unwrap_or(t.len());
    let (num, unit) = (&t[..split], t[split..].trim());
    let Ok(value) = num.parse::<f64>() else {
        refuse!("'{text}' is not a size: expected a number with an optional unit, e.g. 8GiB or 500MB");
    };
    let scale: f64 = match unit.to_ascii_lowercase().as_str() {
        "" | "b" => 1.0,
        "kb" => 1e3,
        "mb" => 1e6,
        "gb" => 1e9,
        "tb" => 1e12,
        "k" | "kib" => 1024.0,
        "m" | "mib" => 1024f64.powi(2),
        "g" | "gib" => 1024f64.powi(3),
        "t" | "tib" => 1024f64.powi(4),
        _ => refuse!("'{text}': unknown size unit '{unit}' (use B, kB, MB, GB, TB, KiB, MiB, GiB or TiB)"),
    };
    let bytes = value * scale;
    if !(bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64) {
        refuse!("'{text}' is not a usable memory size (at least 1 byte)");
    }
    Ok(bytes as u64)
}

/// clap value parser of [`parse_bytes`].
pub fn bytes_arg(text: &str) -> std::result::Result<u64, String> {
    parse_bytes(text).map_err(|e| e.to_string())
}

/// Bytes the system can give without swapping: MemAvailable of /proc/meminfo, lowered to the
/// room left under a cgroup v2 memory limit; `None` when neither can be read.
pub fn available_bytes() -> Option<u64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok();
    let avail = meminfo.as_deref().and_then(|m| {
        let line = m.lines().find(|l| l.starts_with("MemAvailable:"))?;
        let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
        Some(kb * 1024)
    });
    let read = |p: &str| std::fs::read_to_string(p).ok().and_then(|s| s.trim().parse::<u64>().ok());
    let cgroup = match (read("/sys/fs/cgroup/memory.max"), read("/sys/fs/cgroup/memory.current")) {
        (Some(max), Some(cur)) => Some(max.saturating_sub(cur)),
        _ => None,
    };
    match (avail, cgroup) {
        (Some(a), Some(c)) => Some(a.min(c)),
        (a, c) => a.or(c),
    }
}

/// The limit of `--max-memory`: the given value, else [`DEFAULT_SHARE`] of [`available_bytes`]
/// (or of [`FALLBACK_AVAILABLE`]).
pub fn limit(given: Option<u64>) -> u64 {
    given.unwrap_or_else(|| (available_bytes().unwrap_or(FALLBACK_AVAILABLE) as f64 * DEFAULT_SHARE) as u64)
}

/// Refuses a training run whose estimated peak ([`gs_train::training_memory`]) exceeds the limit
/// ([`limit`] of `given`), with the estimate in words; returns the estimate in words otherwise.
pub fn check_train(trainer: &gs_train::Trainer, given: Option<u64>) -> Result<String> {
    let estimate = trainer.memory_estimate();
    let limit = limit(given);
    estimate.check(limit)?;
    Ok(format!(
        "memory estimate: about {} at the peak ({}); limit {}",
        gs_tsdf::format_bytes(estimate.peak_bytes()),
        estimate.describe(),
        gs_tsdf::format_bytes(limit)
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_with_units() {
        assert_eq!(parse_bytes("8GiB").unwrap(), 8 << 30);
        assert_eq!(parse_bytes("500MB").unwrap(), 500_000_000);
        assert_eq!(parse_bytes("1.5 g").unwrap(), 3 << 29);
        assert_eq!(parse_bytes("4096").unwrap(), 4096);
        assert!(parse_bytes("lots").unwrap_err().to_string().contains("not a size"));
        assert!(parse_bytes("3 parsecs").unwrap_err().to_string().contains("unknown size unit"));
        assert!(parse_bytes("0").is_err());
        assert!(limit(None) > 0);
    }
}
