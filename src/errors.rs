//! What every module's errors share. [`Invalid`]: a value or a text that breaks a rule, in words that name the field and the
//! problem (`layers[2].opacity: 1.5 must lie in [0, 1]`). It is the error of parsers and checks,
//! which have no deeper cause to keep; errors with a cause (a file, a library) are enums in their
//! modules that hold the cause as their `source`, and [`chain`] writes an error with its causes
//! for a person to read.

/// A value or text that breaks a rule: the field and the problem, in words.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct Invalid(pub String);

impl Invalid {
    /// The same problem under a field: `field: problem`.
    pub fn at(self, field: impl std::fmt::Display) -> Invalid {
        Invalid(format!("{field}: {}", self.0))
    }

    /// The same problem one step down a dotted path: `path.problem` (a problem that starts with
    /// its own field, as `layer: …`, reads `path.layer: …`).
    pub fn under(self, path: impl std::fmt::Display) -> Invalid {
        Invalid(format!("{path}.{}", self.0))
    }
}

/// A value that breaks its field's rule, the field kept apart from the problem: for checks whose
/// callers name the field their own way (a command-line flag for `steps`, a layer's path, an
/// operation's index). `field` is a dotted path inside the checked value (`brush.radius_m`).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{field}: {problem}")]
pub struct FieldProblem {
    /// The field's path inside the checked value.
    pub field: String,
    /// What is wrong with its value, in words.
    pub problem: String,
}

impl FieldProblem {
    /// The problem of `field`.
    pub fn new(field: impl Into<String>, problem: impl Into<String>) -> FieldProblem {
        FieldProblem { field: field.into(), problem: problem.into() }
    }

    /// The same problem one step down a dotted path: `path.field`.
    pub fn under(self, path: impl std::fmt::Display) -> FieldProblem {
        FieldProblem { field: format!("{path}.{}", self.field), ..self }
    }
}

/// A result whose error, in words, breaks the rule of a named field.
pub trait AtField<T> {
    /// The error as [`Invalid`] under `field`: `field: problem`.
    fn at_field(self, field: impl std::fmt::Display) -> Result<T, Invalid>;
}

impl<T, E: std::fmt::Display> AtField<T> for Result<T, E> {
    fn at_field(self, field: impl std::fmt::Display) -> Result<T, Invalid> {
        self.map_err(|e| Invalid(format!("{field}: {e}")))
    }
}

impl From<String> for Invalid {
    fn from(problem: String) -> Invalid {
        Invalid(problem)
    }
}

impl From<&str> for Invalid {
    fn from(problem: &str) -> Invalid {
        Invalid(problem.into())
    }
}

impl From<Invalid> for String {
    fn from(invalid: Invalid) -> String {
        invalid.0
    }
}

/// The error of a callback or a device that a module calls without knowing its type (the terrain
/// below an edit, a GPU kernel): the caller's error, kept whole as the cause.
pub type Failure = Box<dyn std::error::Error + Send + Sync>;

/// A [`Failure`] that can be cloned into several errors.
pub type SharedFailure = std::sync::Arc<dyn std::error::Error + Send + Sync>;

/// An error and its causes, joined by ": " (what `terrafuse` prints and the workstation shows).
pub fn chain(error: &dyn std::error::Error) -> String {
    let mut text = error.to_string();
    let mut cause = error.source();
    while let Some(c) = cause {
        let more = c.to_string();
        // A cause whose words the error already shows adds nothing.
        if !text.ends_with(&more) {
            text.push_str(": ");
            text.push_str(&more);
        }
        cause = c.source();
    }
    text
}

/// The option closest to `word` when it looks like a typo of it (at most a third of its letters,
/// and at least one, to change by Levenshtein distance), for "did you mean …" in messages.
pub fn closest<'a>(word: &str, options: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    let limit = (word.chars().count() / 3).max(1);
    options
        .into_iter()
        .map(|o| (levenshtein(&word.to_lowercase(), &o.to_lowercase()), o))
        .filter(|(d, _)| *d <= limit)
        .min_by_key(|(d, _)| *d)
        .map(|(_, o)| o)
}

/// Edits (insertions, deletions, substitutions) from `a` to `b`.
fn levenshtein(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let above = row[j + 1];
            row[j + 1] = (above + 1).min(row[j] + 1).min(diagonal + usize::from(ca != *cb));
            diagonal = above;
        }
    }
    row[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_typo_finds_its_word_and_a_stranger_finds_none() {
        let layers = ["sculpt", "lola_global", "erosion"];
        assert_eq!(closest("scuplt", layers), Some("sculpt"));
        assert_eq!(closest("Sculpt", layers), Some("sculpt"));
        assert_eq!(closest("erosoin", layers), Some("erosion"));
        assert_eq!(closest("terrain", layers), None);
        assert_eq!(levenshtein("kitten", "sitting"), 3);
    }

    #[derive(Debug, thiserror::Error)]
    #[error("{path}: cannot read")]
    struct Outer {
        path: String,
        #[source]
        source: std::io::Error,
    }

    #[test]
    fn a_chain_names_every_cause_once() {
        let e = Outer { path: "a.json".into(), source: std::io::Error::other("disk on fire") };
        assert_eq!(chain(&e), "a.json: cannot read: disk on fire");
        assert_eq!(chain(&Invalid::from("x").at("field")), "field: x");
    }
}
