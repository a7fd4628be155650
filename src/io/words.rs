//! Words for messages: the closest of some names to a mistyped one ("did you mean"), and a
//! value quoted for a shell so that a suggested command line can be pasted as printed.

/// Case-insensitive edit distance (Levenshtein) between two names.
pub(crate) fn edit_distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.to_lowercase().chars().collect();
    let b: Vec<char> = b.to_lowercase().chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.iter().enumerate() {
        let mut cur = vec![i + 1; b.len() + 1];
        for (j, cb) in b.iter().enumerate() {
            cur[j + 1] = (prev[j] + usize::from(ca != cb))
                .min(prev[j + 1] + 1)
                .min(cur[j] + 1);
        }
        prev = cur;
    }
    prev[b.len()]
}

/// The name of `candidates` closest to `word` (ignoring case) if it is a likely typo of it: at
/// most one edit per three characters (at least one edit) and fewer edits than either has
/// characters. Ties go to the first candidate.
pub(crate) fn closest<'a>(
    word: &str,
    candidates: impl IntoIterator<Item = &'a str>,
) -> Option<&'a str> {
    let n = word.chars().count();
    if n == 0 || n > 200 {
        return None;
    }
    candidates
        .into_iter()
        .map(|c| (edit_distance(word, c), c))
        .filter(|&(d, c)| d <= (n / 3).max(1) && d < n.min(c.chars().count()))
        .min_by_key(|&(d, _)| d)
        .map(|(_, c)| c)
}

/// `; did you mean `x`?` for the closest of `candidates` to `word` ([`closest`]), or nothing.
pub(crate) fn did_you_mean<'a>(
    word: &str,
    candidates: impl IntoIterator<Item = &'a str>,
) -> String {
    closest(word, candidates)
        .map(|c| format!("; did you mean `{c}`?"))
        .unwrap_or_default()
}

/// `value` as one shell word: as it is when it holds only characters no POSIX shell treats
/// specially (letters, digits, `_ - . , : / + = @ %`), else in single quotes (a single quote
/// inside written as `'\''`), so that `--time-col 't [s]'` pastes as printed.
pub fn shell_quote(value: &str) -> String {
    let plain = !value.is_empty()
        && value
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "_-.,:/+=@%".contains(c));
    if plain {
        value.to_string()
    } else {
        format!("'{}'", value.replace('\'', r"'\''"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closest_finds_one_typo_and_refuses_unrelated_words() {
        let terms = ["poly2", "dahl", "stribeck", "bins", "dbins", "by"];
        assert_eq!(closest("dahll", terms), Some("dahl"));
        assert_eq!(closest("DAHL", terms), Some("dahl"));
        assert_eq!(closest("stribek", terms), Some("stribeck"));
        assert_eq!(closest("bns", terms), Some("bins"));
        // Two edits in four letters, or a word of two letters replaced whole: no guess; one
        // edit in two letters is a guess.
        assert_eq!(closest("xyzw", terms), None);
        assert_eq!(closest("qz", ["by", "ab"]), None);
        assert_eq!(closest("bz", ["by", "ab"]), Some("by"));
        assert_eq!(closest("", terms), None);
        assert_eq!(
            did_you_mean("randm", ["random", "dwell"]),
            "; did you mean `random`?"
        );
        assert_eq!(did_you_mean("qqqqq", ["random", "dwell"]), "");
    }

    #[test]
    fn shell_quote_leaves_plain_words_and_quotes_the_rest() {
        assert_eq!(shell_quote("pos_mm"), "pos_mm");
        assert_eq!(shell_quote("t [s]"), "'t [s]'");
        assert_eq!(shell_quote("F(N)"), "'F(N)'");
        assert_eq!(shell_quote("it's"), r"'it'\''s'");
        assert_eq!(shell_quote(""), "''");
        assert_eq!(shell_quote("x µm"), "'x µm'");
    }
}
