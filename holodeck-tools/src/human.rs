//! Numbers for people: thousands separators and binary byte units.

/// `1234567` as `1,234,567`.
pub fn count(n: u64) -> String {
    let s = n.to_string();
    let mut out = String::with_capacity(s.len() + s.len() / 3);
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i) % 3 == 0 {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// Bytes with a binary unit, e.g. `64.0 MiB`.
pub fn bytes(n: u64) -> String {
    let units = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = n as f64;
    let mut u = 0;
    while v >= 1024.0 && u < units.len() - 1 {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{n} B")
    } else {
        format!("{v:.1} {}", units[u])
    }
}

/// A count with an optional K, M or G suffix (powers of 1000), e.g. `50M` or `2.5k`.
pub fn parse_count(s: &str) -> Result<u64, String> {
    let s = s.trim();
    let (num, mult) = match s.chars().last() {
        Some('K' | 'k') => (&s[..s.len() - 1], 1e3),
        Some('M' | 'm') => (&s[..s.len() - 1], 1e6),
        Some('G' | 'g') => (&s[..s.len() - 1], 1e9),
        _ => (s, 1.0),
    };
    let v: f64 = num.parse().map_err(|_| format!("{s:?} is not a count like 50M"))?;
    if !(v.is_finite() && v >= 0.0) {
        return Err(format!("{s:?} is not a count like 50M"));
    }
    Ok((v * mult).round() as u64)
}

#[cfg(test)]
mod tests {
    #[test]
    fn formats() {
        assert_eq!(super::count(0), "0");
        assert_eq!(super::count(1234567), "1,234,567");
        assert_eq!(super::bytes(1000), "1000 B");
        assert_eq!(super::bytes(64 << 20), "64.0 MiB");
        assert_eq!(super::parse_count("2.5k"), Ok(2500));
        assert_eq!(super::parse_count("100M"), Ok(100_000_000));
        assert!(super::parse_count("-3").is_err() && super::parse_count("lots").is_err());
    }
}
