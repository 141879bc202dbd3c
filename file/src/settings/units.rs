//! Byte sizes (`64M`, `1.5G`) and durations (`90s`, `2h`) as settings write them.

use std::time::Duration;

use super::error::{DurationError, SizeError};

/// Parses a byte size such as `64M`, `1.5G`, `4096` or `0`.
pub fn parse_size(s: &str) -> Result<u64, SizeError> {
    let s = s.trim();
    let (num, mult) = match s.char_indices().last() {
        Some((i, c)) if c.is_ascii_alphabetic() => {
            let mult = match c.to_ascii_uppercase() {
                'K' => 1u64 << 10,
                'M' => 1 << 20,
                'G' => 1 << 30,
                'T' => 1 << 40,
                _ => return Err(SizeError::UnknownUnit(s.to_string())),
            };
            (&s[..i], mult)
        }
        _ => (s, 1),
    };
    let v: f64 = num.trim().parse().map_err(|_| SizeError::NotANumber(s.to_string()))?;
    if !(v.is_finite() && v >= 0.0) {
        return Err(SizeError::Negative(s.to_string()));
    }
    let bytes = (v * mult as f64).round();
    // 2^64 itself is the first value a u64 cannot hold.
    if bytes >= 18_446_744_073_709_551_616.0 {
        return Err(SizeError::TooLarge(s.to_string()));
    }
    Ok(bytes as u64)
}

/// Formats a byte size compactly, exactly (`64M`, `1536K`, `1000`).
pub fn format_size(bytes: u64) -> String {
    for (unit, shift) in [("T", 40), ("G", 30), ("M", 20), ("K", 10)] {
        if bytes != 0 && bytes.is_multiple_of(1u64 << shift) {
            return format!("{}{unit}", bytes >> shift);
        }
    }
    bytes.to_string()
}

/// Parses a duration such as `90s`, `15m`, `2h`; a bare number takes `default_unit` seconds.
pub fn parse_duration(s: &str, default_unit: f64) -> Result<Duration, DurationError> {
    let s = s.trim();
    let (num, unit) = match s.chars().last() {
        Some('s') => (&s[..s.len() - 1], 1.0),
        Some('m') => (&s[..s.len() - 1], 60.0),
        Some('h') => (&s[..s.len() - 1], 3600.0),
        _ => (s, default_unit),
    };
    let v: f64 = num
        .trim()
        .parse()
        .map_err(|_| DurationError::NotANumber(s.to_string()))?;
    if v.is_nan() {
        return Err(DurationError::NotANumber(s.to_string()));
    }
    if v < 0.0 {
        return Err(DurationError::Negative(s.to_string()));
    }
    // Infinite (1e400s parses so) is too long, not negative.
    Duration::try_from_secs_f64(v * unit).map_err(|_| DurationError::TooLong(s.to_string()))
}

/// Formats a duration in seconds (`5400s`), exactly.
pub fn format_duration(d: Duration) -> String {
    format!("{}s", d.as_secs_f64())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_that_are_not_numbers_or_too_long_say_so() {
        assert_eq!(
            parse_duration("nans", 1.0),
            Err(DurationError::NotANumber("nans".into()))
        );
        assert_eq!(parse_duration("nan", 1.0), Err(DurationError::NotANumber("nan".into())));
        assert_eq!(
            parse_duration("1e400s", 1.0),
            Err(DurationError::TooLong("1e400s".into()))
        );
        assert_eq!(parse_duration("inf", 1.0), Err(DurationError::TooLong("inf".into())));
        assert_eq!(parse_duration("-2m", 1.0), Err(DurationError::Negative("-2m".into())));
        assert_eq!(parse_duration("1.5m", 1.0), Ok(Duration::from_secs(90)));
    }

    #[test]
    fn values_that_do_not_parse_say_which_way() {
        assert_eq!(parse_size("1.5K"), Ok(1536));
        assert_eq!(parse_size("-1"), Err(SizeError::Negative("-1".into())));
        assert_eq!(parse_size("lots"), Err(SizeError::UnknownUnit("lots".into())));
        assert_eq!(parse_size("M"), Err(SizeError::NotANumber("M".into())));
        assert_eq!(parse_size("1e10T"), Err(SizeError::TooLarge("1e10T".into())));
        assert_eq!(parse_duration("2m", 1.0), Ok(Duration::from_secs(120)));
        assert_eq!(
            parse_duration("soon", 1.0),
            Err(DurationError::NotANumber("soon".into()))
        );
        assert_eq!(parse_duration("-3s", 1.0), Err(DurationError::Negative("-3s".into())));
        // Far past what a Duration holds: refused, not a panic.
        assert_eq!(
            parse_duration("1e30h", 1.0),
            Err(DurationError::TooLong("1e30h".into()))
        );
    }

    #[test]
    fn sizes_and_durations_print_what_reads_back() {
        for b in [0u64, 1000, 1536, 64 << 20, 3 << 30, (1 << 40) + 1] {
            assert_eq!(parse_size(&format_size(b)), Ok(b));
        }
        for d in [Duration::ZERO, Duration::from_millis(1500), Duration::from_secs(5400)] {
            assert_eq!(parse_duration(&format_duration(d), 3600.0), Ok(d));
        }
    }
}
