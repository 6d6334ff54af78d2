//! Timestamps of a `time` column, read as seconds.
//!
//! Terms:
//! - *timestamp*: a civil date and time without zone, `YYYY/MM/DD-HH:MM:SS`, `YYYY-MM-DD HH:MM:SS` or
//!   `YYYY-MM-DDTHH:MM:SS`, optionally with a fractional second (`05:42:16.25`). A trailing `Z` or UTC
//!   offset (`+02:00`, `-0530`, `+02`, as ISO 8601 loggers write) is accepted; an offset is taken out, so
//!   that a file whose offset changes (summer time) keeps true differences.
//! - *epoch seconds*: seconds since 1970-01-01 00:00:00 of the same (unknown, assumed constant) zone; only
//!   differences are used, so the zone does not matter.

/// Parses one timestamp into epoch seconds; `None` if `s` is not one of the accepted forms.
pub(crate) fn parse_timestamp(s: &str) -> Option<f64> {
    parse_timestamp_parts(s).map(|(whole, frac)| whole as f64 + frac)
}

/// Seconds from timestamp `t0` to `t`, both of [`parse_timestamp_parts`]: whole seconds subtracted as
/// integers, so that the difference keeps the fraction exactly (epoch seconds as one `f64` near 1.7·10⁹
/// keep only about 0.2 µs, which made `12.44` read as `12.440000057`).
pub(crate) fn seconds_between(t0: (i64, f64), t: (i64, f64)) -> f64 {
    (t.0 - t0.0) as f64 + (t.1 - t0.1)
}

/// Parses one timestamp into whole epoch seconds and the fraction of a second (`0 ≤ frac < 1`).
pub(crate) fn parse_timestamp_parts(s: &str) -> Option<(i64, f64)> {
    let s = s.trim();
    let s = s.strip_suffix('Z').unwrap_or(s);
    let b = s.as_bytes();
    if b.len() < 19 {
        return None;
    }
    let date_sep = b[4];
    if !(date_sep == b'-' || date_sep == b'/') || b[7] != date_sep {
        return None;
    }
    if !matches!(b[10], b'-' | b' ' | b'T') || b[13] != b':' || b[16] != b':' {
        return None;
    }
    let num = |from: usize, to: usize| -> Option<i64> {
        let part = &s[from..to];
        if part.bytes().all(|c| c.is_ascii_digit()) {
            part.parse().ok()
        } else {
            None
        }
    };
    let (year, month, day) = (num(0, 4)?, num(5, 7)?, num(8, 10)?);
    let (hour, minute, second) = (num(11, 13)?, num(14, 16)?, num(17, 19)?);
    if !(1..=12).contains(&month)
        || day < 1
        || day > days_in_month(year, month)
        || hour > 23
        || minute > 59
        || second > 60
    {
        return None;
    }
    // After the seconds: an optional fraction, then an optional UTC offset (`+02:00`, `-0530`, `+02`).
    let mut rest = &s[19..];
    let mut frac = 0.0;
    if let Some(r) = rest.strip_prefix('.') {
        let n = r.bytes().take_while(u8::is_ascii_digit).count();
        if n == 0 {
            return None;
        }
        frac = format!("0.{}", &r[..n]).parse::<f64>().ok()?;
        rest = &r[n..];
    }
    let offset_s = if rest.is_empty() {
        0
    } else {
        utc_offset_s(rest)?
    };
    let days = days_from_civil(year, month, day);
    Some((
        days * 86_400 + hour * 3600 + minute * 60 + second - offset_s,
        frac,
    ))
}

/// A UTC offset `+HH:MM`, `+HHMM` or `+HH` (or with `-`) in seconds; `None` if `s` is not one.
fn utc_offset_s(s: &str) -> Option<i64> {
    let sign = match s.as_bytes().first()? {
        b'+' => 1,
        b'-' => -1,
        _ => return None,
    };
    let digits: String = s[1..].chars().filter(|&c| c != ':').collect();
    let colons = s[1..].matches(':').count();
    let ok_shape = match digits.len() {
        2 => colons == 0,
        4 => colons == 0 || (colons == 1 && s.as_bytes().get(3) == Some(&b':')),
        _ => false,
    };
    if !ok_shape || !digits.bytes().all(|c| c.is_ascii_digit()) {
        return None;
    }
    let h: i64 = digits[..2].parse().ok()?;
    let m: i64 = if digits.len() == 4 {
        digits[2..].parse().ok()?
    } else {
        0
    };
    if h > 23 || m > 59 {
        return None;
    }
    Some(sign * (h * 3600 + m * 60))
}

fn is_leap(y: i64) -> bool {
    (y % 4 == 0 && y % 100 != 0) || y % 400 == 0
}

fn days_in_month(y: i64, m: i64) -> i64 {
    match m {
        1 | 3 | 5 | 7 | 8 | 10 | 12 => 31,
        4 | 6 | 9 | 11 => 30,
        _ if is_leap(y) => 29,
        _ => 28,
    }
}

/// Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's `days_from_civil`).
fn days_from_civil(y: i64, m: i64, d: i64) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (m + 9) % 12;
    let doy = (153 * mp + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_three_contract_forms_agree() {
        // Reference: 2021-06-13 05:42:16 UTC is Unix time 1623562936 (date -u -d '2021-06-13 05:42:16' +%s).
        let want = 1_623_562_936.0;
        assert_eq!(parse_timestamp("2021/06/13-05:42:16"), Some(want));
        assert_eq!(parse_timestamp("2021-06-13 05:42:16"), Some(want));
        assert_eq!(parse_timestamp("2021-06-13T05:42:16"), Some(want));
        assert_eq!(parse_timestamp("2021-06-13T05:42:16Z"), Some(want));
        assert_eq!(parse_timestamp("2021-06-13T05:42:16.25"), Some(want + 0.25));
    }

    #[test]
    fn utc_offsets_are_taken_out() {
        // 05:42:16+02:00 is 03:42:16 UTC: 2 h before the same clock time in UTC.
        let utc = parse_timestamp("2021-06-13T05:42:16Z").unwrap();
        assert_eq!(
            parse_timestamp("2021-06-13T05:42:16+02:00"),
            Some(utc - 7200.0)
        );
        assert_eq!(
            parse_timestamp("2021-06-13 05:42:16+0200"),
            Some(utc - 7200.0)
        );
        assert_eq!(
            parse_timestamp("2021-06-13T05:42:16+02"),
            Some(utc - 7200.0)
        );
        assert_eq!(
            parse_timestamp("2021-06-13T05:42:16.5-05:30"),
            Some(utc + 19800.0 + 0.5)
        );
        for bad in [
            "2021-06-13T05:42:16+2",
            "2021-06-13T05:42:16+02:0",
            "2021-06-13T05:42:16+24:00",
            "2021-06-13T05:42:16 +02:00",
            "2021-06-13T05:42:16.+02:00",
        ] {
            assert_eq!(parse_timestamp(bad), None, "{bad}");
        }
    }

    #[test]
    fn differences_keep_the_fraction() {
        // 12.44 s after 08:00:00 (a `time_s` of 12.44 written as a timestamp): exact to 1e-12 s; the
        // difference of two f64 epoch seconds was off by 5.7e-8 s.
        let t0 = parse_timestamp_parts("2024-01-02T08:00:00").unwrap();
        let t = parse_timestamp_parts("2024-01-02T08:00:12.440").unwrap();
        assert!((seconds_between(t0, t) - 12.44).abs() < 1e-12);
    }

    #[test]
    fn epoch_and_leap_day() {
        assert_eq!(parse_timestamp("1970-01-01 00:00:00"), Some(0.0));
        // 2000-03-01 is 11017 days after the epoch (2000 is a leap year).
        assert_eq!(
            parse_timestamp("2000-03-01 00:00:00"),
            Some(11_017.0 * 86_400.0)
        );
        assert!(parse_timestamp("2000-02-29 00:00:00").is_some());
        assert!(parse_timestamp("2001-02-29 00:00:00").is_none());
    }

    #[test]
    fn rejects_non_timestamps() {
        for s in [
            "",
            "12.5",
            "2021-06-13",
            "2021-13-01 00:00:00",
            "2021-06-13 25:00:00",
            "2021-06-13 05:42:16x",
            "2021/06-13 05:42:16",
        ] {
            assert_eq!(parse_timestamp(s), None, "{s}");
        }
    }
}
