//! Decimal numbers from bytes, fast: scene and model files are almost all
//! numbers like `-0.123456` or `1e-16`, and parsing them is most of the
//! time a big file takes to read.

/// Powers of ten that f64 holds exactly.
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// The number `text` spells, as Rust's `f64` parser reads it (the same
/// value, bit for bit), or None where that parser would fail.
///
/// Clinger's fast path first: when the digits form an integer m below 2^53
/// and the decimal exponent e lies within ±22, both m and 10^|e| are exact
/// in f64, so one correctly rounded multiplication or division gives the
/// correctly rounded value, which is what the standard parser returns.
/// Everything else (more digits, larger exponents, `inf`, `nan`, errors)
/// goes to the standard parser, which needs the bytes as UTF-8 first.
pub fn parse_f64(text: &[u8]) -> Option<f64> {
    fast_path(text).or_else(|| std::str::from_utf8(text).ok()?.parse().ok())
}

fn fast_path(text: &[u8]) -> Option<f64> {
    let (negative, mut rest) = match text.split_first()? {
        (b'-', r) => (true, r),
        (b'+', r) => (false, r),
        _ => (false, text),
    };
    let mut mantissa: u64 = 0;
    let mut digits = 0u32;
    let mut exponent: i32 = 0;
    let whole = take_digits(&mut rest, &mut mantissa, &mut digits);
    let mut any = whole > 0;
    if let Some((b'.', r)) = rest.split_first() {
        rest = r;
        let fraction = take_digits(&mut rest, &mut mantissa, &mut digits);
        exponent -= fraction as i32;
        any |= fraction > 0;
    }
    if !any || digits > 15 {
        return None;
    }
    if let Some((b'e' | b'E', r)) = rest.split_first() {
        let (sign, mut r) = match r.split_first()? {
            (b'-', r) => (-1, r),
            (b'+', r) => (1, r),
            _ => (1, r),
        };
        let mut e: i32 = 0;
        let start = r.len();
        while let Some((&c, rr)) = r.split_first() {
            if !c.is_ascii_digit() || e > 10_000 {
                return None;
            }
            e = e * 10 + i32::from(c - b'0');
            r = rr;
        }
        if r.len() == start {
            return None;
        }
        exponent += sign * e;
        rest = r;
    }
    if !rest.is_empty() || mantissa >= 1 << 53 {
        return None;
    }
    let m = mantissa as f64;
    let value = if exponent >= 0 {
        m * *POW10.get(exponent as usize)?
    } else {
        m / *POW10.get(exponent.unsigned_abs() as usize)?
    };
    Some(if negative { -value } else { value })
}

/// Reads the digits at the start of `rest` into `mantissa` (wrapping: the
/// caller gives up past 15 significant `digits`); returns how many.
fn take_digits(rest: &mut &[u8], mantissa: &mut u64, digits: &mut u32) -> usize {
    let mut n = 0;
    while let Some((&c, r)) = rest.split_first() {
        if !c.is_ascii_digit() {
            break;
        }
        // Leading zeros are not significant digits.
        if *mantissa != 0 || c != b'0' {
            *digits += 1;
        }
        *mantissa = mantissa.wrapping_mul(10).wrapping_add(u64::from(c - b'0'));
        *rest = r;
        n += 1;
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn std_parse(s: &str) -> Option<f64> {
        s.parse().ok()
    }

    fn same(a: Option<f64>, b: Option<f64>) -> bool {
        match (a, b) {
            (Some(x), Some(y)) => x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()),
            (None, None) => true,
            _ => false,
        }
    }

    #[test]
    fn course_forms_and_edge_cases_match_the_standard_parser() {
        for s in [
            "1",
            ".44",
            "1e-16",
            "-0",
            "0",
            "-0.0",
            "+3",
            "1.",
            "0.1",
            "123456789012345",
            "1234567890123456",
            "9007199254740993",
            "1e22",
            "1e23",
            "1e-22",
            "1e-23",
            "5e-324",
            "1.7976931348623157e308",
            "inf",
            "-inf",
            "nan",
            "NaN",
            "",
            "-",
            "+",
            ".",
            "e5",
            "1e",
            "1e+",
            "1e-",
            "1.2.3",
            "1x",
            "0x10",
            " 1",
            "1 ",
            "00000000000000000001.5",
            "0.000000000000000000001",
            "-.5e1",
            "3.4028235e38",
        ] {
            assert!(
                same(parse_f64(s.as_bytes()), std_parse(s)),
                "{s:?}: {:?} vs {:?}",
                parse_f64(s.as_bytes()),
                std_parse(s)
            );
        }
    }

    proptest! {
        /// Any decimal the scene files could hold parses to the standard
        /// parser's bits.
        #[test]
        fn decimals_match_the_standard_parser(
            sign in prop::sample::select(vec!["", "-", "+"]),
            int in "[0-9]{0,12}",
            frac in prop::option::of("[0-9]{0,12}"),
            exp in prop::option::of(-40i32..40),
        ) {
            let mut s = format!("{sign}{int}");
            if let Some(f) = &frac {
                s.push('.');
                s.push_str(f);
            }
            if let Some(e) = exp {
                s.push_str(&format!("e{e}"));
            }
            prop_assert!(same(parse_f64(s.as_bytes()), std_parse(&s)), "{s:?}");
        }

        #[test]
        fn any_f64_written_back_parses_to_itself(bits in any::<u64>()) {
            let x = f64::from_bits(bits);
            for s in [format!("{x}"), format!("{x:e}"), format!("{x:.6}")] {
                prop_assert!(same(parse_f64(s.as_bytes()), std_parse(&s)), "{s:?}");
            }
        }
    }
}
