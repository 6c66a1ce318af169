//! Wording shared by messages a user reads.

/// A count with its noun, singular for one: "1 pure pixel", "3 pure pixels" (the nouns we
/// count take an "s").
pub fn counted(n: impl Into<u64>, noun: &str) -> String {
    let n = n.into();
    let s = if n == 1 { "" } else { "s" };
    format!("{n} {noun}{s}")
}

#[cfg(test)]
mod tests {
    use super::counted;

    #[test]
    fn one_is_singular_and_every_other_count_plural() {
        assert_eq!(counted(1u32, "pure pixel"), "1 pure pixel");
        assert_eq!(counted(0u32, "pixel"), "0 pixels");
        assert_eq!(counted(2u64, "texel"), "2 texels");
    }
}
