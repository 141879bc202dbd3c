//! Numbers for people: thousands separators and binary byte units.

/// `1234567` as `1,234,567`.
pub fn count(n: u64) -> String {
    let s = n.to_string();
    let mut out = String::with_capacity(s.len() + s.len() / 3);
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
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

/// A count that does not parse.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CountError {
    /// Not a non-negative number with an optional K, M or G.
    #[error("{0:?} is not a count like 50M")]
    NotACount(String),
    /// A whole count above 2^64.
    #[error("{0:?} is more than 64 bits can count")]
    TooLarge(String),
    /// A count outside what the flag accepts.
    #[error("{text:?} is outside {min}..={max}")]
    OutOfRange {
        /// The count as given.
        text: String,
        /// The least accepted.
        min: u64,
        /// The most accepted.
        max: u64,
    },
}

/// A count with an optional K, M or G suffix (powers of 1000), e.g. `50M` or `2.5k`.
pub fn parse_count(s: &str) -> Result<u64, CountError> {
    let s = s.trim();
    let (num, mult) = match s.chars().last() {
        Some('K' | 'k') => (&s[..s.len() - 1], 1e3),
        Some('M' | 'm') => (&s[..s.len() - 1], 1e6),
        Some('G' | 'g') => (&s[..s.len() - 1], 1e9),
        _ => (s, 1.0),
    };
    let v: f64 = num.parse().map_err(|_| CountError::NotACount(s.to_string()))?;
    if !(v.is_finite() && v >= 0.0) {
        return Err(CountError::NotACount(s.to_string()));
    }
    let n = (v * mult).round();
    // 2^64 itself is the first value a u64 cannot hold.
    if n >= 18_446_744_073_709_551_616.0 {
        return Err(CountError::TooLarge(s.to_string()));
    }
    Ok(n as u64)
}

/// A clap value parser of counts (as [`parse_count`]) from `min` to `max`:
/// flags whose numbers size an allocation refuse what cannot be allocated.
pub fn count_in(min: u64, max: u64) -> impl Fn(&str) -> Result<u64, CountError> + Clone + Send + Sync + 'static {
    move |s| {
        let n = parse_count(s)?;
        if (min..=max).contains(&n) {
            Ok(n)
        } else {
            Err(CountError::OutOfRange {
                text: s.trim().to_string(),
                min,
                max,
            })
        }
    }
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
        assert_eq!(super::parse_count("-3"), Err(super::CountError::NotACount("-3".into())));
        assert_eq!(
            super::parse_count("lots"),
            Err(super::CountError::NotACount("lots".into()))
        );
        assert_eq!(
            super::parse_count("1e30G"),
            Err(super::CountError::TooLarge("1e30G".into()))
        );
    }
}
