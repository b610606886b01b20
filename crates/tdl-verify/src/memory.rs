//! The memory bound of a search ([`crate::Options::max_memory`]): its default, sized to the
//! machine, and what the search measures against it.
//!
//! The search compares the process's resident set (`VmRSS` in `/proc/self/status`: what the kernel
//! counts when it runs out of memory) with the bound every [`CHECK_EVERY`] states it expands, a
//! read of a small file every few milliseconds. Where that file cannot be read (not Linux), it
//! compares an estimate of its state store instead ([`estimate`]).

/// How many states the search expands between two looks at its memory.
pub(crate) const CHECK_EVERY: u64 = 1024;

/// What is used when the machine's memory cannot be read: 4 GiB.
const FALLBACK: u64 = 4 << 30;

/// The default memory bound: half of the machine's memory (`MemTotal` in `/proc/meminfo`), or of
/// the cgroup's limit (`/sys/fs/cgroup/memory.max`) when lower; 4 GiB when neither can be read.
/// Half leaves room for what the search allocates between two looks and for the rest of the
/// machine.
pub fn default_max_memory() -> u64 {
    let total = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|s| kilobytes(&s, "MemTotal:"));
    let cgroup = std::fs::read_to_string("/sys/fs/cgroup/memory.max")
        .ok()
        .and_then(|s| s.trim().parse::<u64>().ok());
    match (total, cgroup) {
        (Some(t), Some(c)) => t.min(c) / 2,
        (Some(t), None) => t / 2,
        (None, Some(c)) => c / 2,
        (None, None) => FALLBACK,
    }
}

/// The value of a `Key:   N kB` line, in bytes.
fn kilobytes(text: &str, key: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with(key))?;
    let n: u64 = line[key.len()..]
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse()
        .ok()?;
    n.checked_mul(1024)
}

/// The process's resident set, in bytes, if the system says.
pub(crate) fn resident() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    kilobytes(&status, "VmRSS:")
}

/// An estimate of the search's state store, in bytes, where the resident set cannot be read:
/// per distinct state its record (16 bytes) and its slot in the table of fingerprints (about 24),
/// per transition its edge (12), and per state waiting to be expanded 2 KiB (an engine whose
/// nodes it shares with others: the Xavier mission's search peaks at about a gigabyte with a
/// million states queued).
pub(crate) fn estimate(distinct: usize, edges: usize, queued: usize) -> u64 {
    (distinct as u64 * 40) + (edges as u64 * 12) + (queued as u64 * 2048)
}

/// What the search measures against its bound: the resident set, else [`estimate`].
pub(crate) fn used(distinct: usize, edges: usize, queued: usize) -> u64 {
    resident().unwrap_or_else(|| estimate(distinct, edges, queued))
}

/// A size for people: `512 MB`, `1.50 GB` (powers of 1024).
pub fn fmt_bytes(n: u64) -> String {
    const MB: f64 = (1u64 << 20) as f64;
    const GB: f64 = (1u64 << 30) as f64;
    let x = n as f64;
    if x >= GB {
        format!("{:.2} GB", x / GB)
    } else if x >= MB {
        format!("{:.0} MB", x / MB)
    } else {
        format!("{:.0} kB", x / 1024.0)
    }
}

/// Parses a size: a number of bytes, or with a unit `K`, `M`, `G`, `T` (powers of 1024; `KB`,
/// `KiB` and lower case alike), e.g. `512M`, `1.5G`.
pub fn parse_size(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let unit = unit.trim().to_ascii_lowercase();
    let scale: u64 = match unit.trim_end_matches('b').trim_end_matches('i') {
        "" => 1,
        "k" => 1 << 10,
        "m" => 1 << 20,
        "g" => 1 << 30,
        "t" => 1 << 40,
        _ => return Err(format!("`{text}` is not a size: write e.g. 512M, 2G, 1.5G")),
    };
    let n: f64 = number
        .parse()
        .map_err(|_| format!("`{text}` is not a size: write e.g. 512M, 2G, 1.5G"))?;
    let bytes = n * scale as f64;
    if !bytes.is_finite() || bytes < 1.0 || bytes >= u64::MAX as f64 {
        return Err(format!("`{text}` is not a size this machine can bound"));
    }
    Ok(bytes as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_their_units() {
        assert_eq!(parse_size("1024"), Ok(1024));
        assert_eq!(parse_size("512M"), Ok(512 << 20));
        assert_eq!(parse_size("2g"), Ok(2 << 30));
        assert_eq!(parse_size("1.5GiB"), Ok(3 << 29));
        assert_eq!(parse_size("64 KB"), Ok(64 << 10));
        assert!(parse_size("lots").is_err());
        assert!(parse_size("12Q").is_err());
        assert!(parse_size("0").is_err());
    }

    #[test]
    fn meminfo_lines_read_in_bytes() {
        let text = "MemTotal:       24684096 kB\nMemFree:        16691096 kB\n";
        assert_eq!(kilobytes(text, "MemTotal:"), Some(24_684_096 * 1024));
        assert_eq!(kilobytes(text, "VmRSS:"), None);
    }

    #[test]
    fn the_default_is_a_fraction_of_the_machine() {
        let d = default_max_memory();
        assert!(d >= 64 << 20, "{d}");
        if let Some(total) = std::fs::read_to_string("/proc/meminfo")
            .ok()
            .and_then(|s| kilobytes(&s, "MemTotal:"))
        {
            assert!(d <= total / 2, "{d} of {total}");
        }
    }

    #[test]
    fn the_resident_set_is_read_on_linux() {
        if cfg!(target_os = "linux") {
            assert!(resident().is_some_and(|r| r > 0));
        }
        assert_eq!(estimate(10, 100, 1), 400 + 1200 + 2048);
    }
}
