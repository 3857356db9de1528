//! Numbers in messages as a person reads them ([`readable`]).

/// Significant digits kept: enough for every value a person types or a datasheet gives,
/// few enough that the noise of a computed value (0.1 + 0.2 = 0.30000000000000004, a bound
/// like 1e8 / 1e-6) is rounded away.
const DIGITS: usize = 12;

/// `x` for a message: at most 12 significant digits, no trailing zeros; plain for
/// 1e-3 <= |x| < 1e6 (`0.01`, `6.5`, `20000`), elsewhere the shorter of plain and
/// scientific (`1e300`, `2.5e-12`, `1e-4`, but `6894800`); `NaN`, `inf`, `-inf`.
/// (`format!("{x}")` writes 1e300 with 301 digits.)
pub fn readable(x: f64) -> String {
    if !x.is_finite() {
        return if x.is_nan() {
            "NaN"
        } else if x > 0.0 {
            "inf"
        } else {
            "-inf"
        }
        .to_string();
    }
    if x == 0.0 {
        return "0".to_string();
    }
    // Rounded to DIGITS significant digits: "d.ddddde-7"; the exponent is the rounded one.
    let text = format!("{:.*e}", DIGITS - 1, x.abs());
    let (mantissa, exponent) = text.split_once('e').expect("LowerExp writes an exponent");
    let exponent: i32 = exponent.parse().expect("LowerExp's exponent is an integer");
    let digits = mantissa.replace('.', "");
    let digits = digits.trim_end_matches('0');
    let sign = if x < 0.0 { "-" } else { "" };
    let plain = plain_text(digits, exponent);
    let scientific = match digits.split_at(1) {
        (first, "") => format!("{first}e{exponent}"),
        (first, rest) => format!("{first}.{rest}e{exponent}"),
    };
    let prefer_plain = (-3..6).contains(&exponent) || plain.len() <= scientific.len();
    format!("{sign}{}", if prefer_plain { plain } else { scientific })
}

/// The significant `digits` (no leading or trailing zeros) times 10^(`exponent` + 1 -
/// their count), written without an exponent.
fn plain_text(digits: &str, exponent: i32) -> String {
    let n = digits.len() as i32;
    if exponent < 0 {
        format!("0.{}{digits}", "0".repeat((-exponent - 1) as usize))
    } else if exponent + 1 >= n {
        format!("{digits}{}", "0".repeat((exponent + 1 - n) as usize))
    } else {
        let (whole, fraction) = digits.split_at(exponent as usize + 1);
        format!("{whole}.{fraction}")
    }
}

#[cfg(test)]
mod tests {
    use super::readable;

    #[test]
    fn numbers_as_a_person_reads_them() {
        let cases = [
            (1e300, "1e300"),
            (0.01, "0.01"),
            (6.8948e6, "6894800"),
            (1e-300, "1e-300"),
            (-1e-300, "-1e-300"),
            (2.5e-12, "2.5e-12"),
            (0.1 + 0.2, "0.3"),
            (1e8 / 1e-6, "1e14"),
            (1e-4, "1e-4"),
            (1e-3, "0.001"),
            (0.0015, "0.0015"),
            (1e6, "1e6"),
            (999_999.0, "999999"),
            (1.5e7, "1.5e7"),
            (12_345_678.0, "12345678"),
            (20_000.0, "20000"),
            (160_000.0, "160000"),
            (-101_325.0, "-101325"),
            (3.2, "3.2"),
            (-0.04, "-0.04"),
            (1.0, "1"),
            (0.0, "0"),
            (-0.0, "0"),
            (123.456_789_012_345, "123.456789012"),
            (f64::MAX, "1.79769313486e308"),
            (5e-324, "4.94065645841e-324"),
            (f64::NAN, "NaN"),
            (f64::INFINITY, "inf"),
            (f64::NEG_INFINITY, "-inf"),
        ];
        for (x, text) in cases {
            assert_eq!(readable(x), text, "{x:e}");
        }
    }

    /// What a person reads is the value to its last shown digit: parsed back, it is the
    /// value within a unit of the twelfth significant digit.
    #[test]
    fn the_text_is_the_value() {
        let mut x: f64 = 1.234_567_89e-310;
        while x < 1e308 {
            for v in [x, -x, x.next_up(), 1.0 / x].into_iter().filter(|v| v.is_finite()) {
                let back: f64 = readable(v).parse().unwrap();
                assert!((back - v).abs() <= 1e-11 * v.abs(), "{v:e}: {}", readable(v));
            }
            x *= 7.3;
        }
    }
}
