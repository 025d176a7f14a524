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
/// Clinger's fast path first (`parse_prefix`); everything else (more
/// digits, larger exponents, `inf`, `nan`, errors) goes to the standard
/// parser, which needs the bytes as UTF-8 first.
pub fn parse_f64(text: &[u8]) -> Option<f64> {
    match parse_prefix(text) {
        Some((value, len)) if len == text.len() => Some(value),
        _ => std::str::from_utf8(text).ok()?.parse().ok(),
    }
}

/// The decimal number at the start of `text` and how many bytes it takes,
/// when Clinger's fast path gives it exactly: at most 19 digits (so the
/// integer m they form cannot overflow), m below 2^53 and the decimal
/// exponent e within ±22. Then m and 10^|e| are exact in f64, so one
/// correctly rounded multiplication or division gives the correctly
/// rounded value, which is what the standard parser returns for the same
/// bytes. None otherwise (the caller falls back to `parse_f64`'s standard
/// parser). Scene files are almost all such numbers, and the parser reads
/// them here straight from the input, without first finding where the
/// token ends.
pub fn parse_prefix(text: &[u8]) -> Option<(f64, usize)> {
    let (negative, mut i) = match text.first()? {
        b'-' => (true, 1),
        b'+' => (false, 1),
        _ => (false, 0),
    };
    let mut mantissa: u64 = 0;
    let whole = take_digits(text, &mut i, &mut mantissa);
    let mut exponent: i32 = 0;
    let mut digits = whole;
    if text.get(i) == Some(&b'.') {
        i += 1;
        let fraction = take_digits(text, &mut i, &mut mantissa);
        exponent = -(fraction as i32);
        digits += fraction;
    }
    if digits == 0 || digits > 19 {
        return None;
    }
    if let Some(b'e' | b'E') = text.get(i) {
        i += 1;
        let sign = match text.get(i) {
            Some(b'-') => {
                i += 1;
                -1
            }
            Some(b'+') => {
                i += 1;
                1
            }
            _ => 1,
        };
        let mut e: u64 = 0;
        let n = take_digits(text, &mut i, &mut e);
        // Past four digits the exponent is out of the fast path's range
        // anyway; the standard parser sorts it out.
        if n == 0 || n > 4 {
            return None;
        }
        exponent += sign * e as i32;
    }
    if mantissa >= 1 << 53 {
        return None;
    }
    let m = mantissa as f64;
    let value = if exponent >= 0 {
        m * *POW10.get(exponent as usize)?
    } else {
        m / *POW10.get(exponent.unsigned_abs() as usize)?
    };
    Some((if negative { -value } else { value }, i))
}

/// Reads the digits of `text` from `*i` on into `value` (wrapping: callers
/// give up past 19 of them); returns how many.
fn take_digits(text: &[u8], i: &mut usize, value: &mut u64) -> usize {
    let start = *i;
    while let Some(&c) = text.get(*i) {
        let d = c.wrapping_sub(b'0');
        if d > 9 {
            break;
        }
        *value = value.wrapping_mul(10).wrapping_add(u64::from(d));
        *i += 1;
    }
    *i - start
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

    #[test]
    fn a_prefix_is_read_up_to_where_the_number_ends() {
        assert_eq!(parse_prefix(b"-20.5 nor:"), Some((-20.5, 5)));
        assert_eq!(parse_prefix(b".44\n"), Some((0.44, 3)));
        assert_eq!(parse_prefix(b"1e-16 "), Some((1e-16, 5)));
        // The caller sees the number does not end at whitespace.
        assert_eq!(parse_prefix(b"1x"), Some((1.0, 1)));
        for s in [
            "1e ",
            "1e+ ",
            ". ",
            "- ",
            "12345678901234567890 ",
            "1e99999 ",
        ] {
            assert_eq!(parse_prefix(s.as_bytes()), None, "{s:?}");
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
