//! The layout of a text file, told from its content: comment lines (`#`, `%` as MATLAB's ASCII
//! files write them), the separator (comma, semicolon, tab or runs of whitespace) and whether
//! the first line is a header, which it is only when none of its fields is a number: a numeric
//! first line is data, never swallowed.

/// How the fields of a line are separated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Separator {
    Comma,
    Semicolon,
    Tab,
    Whitespace,
}

impl Separator {
    /// The fields of `line`, trimmed.
    pub(super) fn split(self, line: &str) -> Vec<&str> {
        match self {
            Separator::Comma => line.split(',').map(str::trim).collect(),
            Separator::Semicolon => line.split(';').map(str::trim).collect(),
            Separator::Tab => line.split('\t').map(str::trim).collect(),
            Separator::Whitespace => line.split_whitespace().collect(),
        }
    }

    /// The name used in messages.
    pub(super) fn name(self) -> &'static str {
        match self {
            Separator::Comma => "comma",
            Separator::Semicolon => "semicolon",
            Separator::Tab => "tab",
            Separator::Whitespace => "whitespace",
        }
    }
}

/// A line that carries no data: blank, or a comment.
pub(super) fn is_comment(line: &str) -> bool {
    line.is_empty() || line.starts_with('#') || line.starts_with('%')
}

/// The separator of the content lines `sample` (comments already left out): the first of
/// semicolon, tab and comma found on every line, else whitespace. A semicolon comes first
/// because files that separate with it may write decimal commas; a tab before a comma because
/// a tab-separated label may hold one.
pub(super) fn separator(sample: &[&str]) -> Separator {
    let on_every = |c: char| !sample.is_empty() && sample.iter().all(|l| l.contains(c));
    if on_every(';') {
        Separator::Semicolon
    } else if on_every('\t') {
        Separator::Tab
    } else if on_every(',') {
        Separator::Comma
    } else {
        Separator::Whitespace
    }
}

/// True if a field is a number as this reader parses them.
pub(super) fn is_number(field: &str) -> bool {
    field.parse::<f64>().is_ok()
}

/// The header's names when `first` (the first content line) is a header: no field is a number.
pub(super) fn header(first: &str, sep: Separator) -> Option<Vec<String>> {
    let fields = sep.split(first);
    (!fields.iter().any(|f| is_number(f))).then(|| fields.iter().map(|f| f.to_string()).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn separators_and_headers_by_content() {
        assert_eq!(separator(&["1,2,3", "4,5,6"]), Separator::Comma);
        assert_eq!(separator(&["1;2,5;3", "4;5;6"]), Separator::Semicolon);
        assert_eq!(separator(&["1\t2\t3", "t\tax\tpart, a"]), Separator::Tab);
        assert_eq!(separator(&["1  2 3", " 4 5\t6"]), Separator::Whitespace);
        assert_eq!(
            Separator::Whitespace.split(" 1  2\t3 "),
            vec!["1", "2", "3"]
        );
        let sep = Separator::Comma;
        assert_eq!(header("t, ax", sep), Some(vec!["t".into(), "ax".into()]));
        // A numeric first line is data, whatever else it holds.
        assert_eq!(header("0.0, 1.2, x", sep), None);
        assert_eq!(header("1e3,2", sep), None);
        assert!(is_comment("% MATLAB comment") && is_comment("# c") && is_comment(""));
    }
}
