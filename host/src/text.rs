//! Wording shared by messages a user reads.

/// A count with its noun, singular for one: "1 pure pixel", "3 pure pixels" (the nouns we
/// count take an "s").
pub fn counted(n: impl Into<u64>, noun: &str) -> String {
    let n = n.into();
    let s = if n == 1 { "" } else { "s" };
    format!("{n} {noun}{s}")
}

/// A number to 4 significant digits, without trailing zeros: "100000", "0.6", "0.0003123",
/// and with an exponent from a million up and below 1e-4: "1e15", "1e-300" (a number in
/// a message, where `{:.4}` gave "100000.0000" and `{}` 300 zeros).
pub fn significant(x: f64) -> String {
    match format!("{x:.3e}").parse::<f64>() {
        Ok(rounded) if rounded.abs() >= 1e6 || (rounded != 0.0 && rounded.abs() < 1e-4) => {
            format!("{rounded:e}")
        }
        Ok(rounded) => format!("{rounded}"),
        Err(_) => format!("{x}"),
    }
}

#[cfg(test)]
mod tests {
    use super::{counted, significant};

    #[test]
    fn lengths_are_given_to_four_digits() {
        assert_eq!(significant(100000.0), "100000");
        assert_eq!(significant(0.6000000238418579), "0.6");
        assert_eq!(significant(0.00031234567), "0.0003123");
        assert_eq!(significant(14.142135), "14.14");
        assert_eq!(significant(1e15), "1e15");
        assert_eq!(significant(-1.23456e20), "-1.235e20");
        assert_eq!(significant(1e-300), "1e-300");
        assert_eq!(significant(0.0), "0");
    }

    #[test]
    fn one_is_singular_and_every_other_count_plural() {
        assert_eq!(counted(1u32, "pure pixel"), "1 pure pixel");
        assert_eq!(counted(0u32, "pixel"), "0 pixels");
        assert_eq!(counted(2u64, "texel"), "2 texels");
    }
}
