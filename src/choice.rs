//! Closed sets of named choices — methods, precisions, models, backends,
//! table formats — under the names the files and flags use. The command line
//! turns each into a clap value list (`cli::value_enum!`); the typed API and
//! the Python module parse them with [`Choice::parse_flag`], whose error
//! lists the possible values, as clap's does.

use crate::error::{flag, InputError};

/// A closed set of named values.
pub trait Choice: Sized + Copy + 'static {
    /// Every value, in the order messages list them.
    const ALL: &'static [Self];
    /// The value's name in files and on the command line.
    fn name(self) -> &'static str;

    /// The value named `s`, if any.
    fn from_name(s: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|c| c.name() == s)
    }

    /// The names, comma-separated.
    fn names() -> String {
        Self::ALL
            .iter()
            .map(|c| c.name())
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// The value named `value` of the setting `flag`, or an error that
    /// names the flag and lists the possible values.
    ///
    /// ```
    /// use hertz_cradle::choice::Choice;
    /// use hertz_cradle::scene::Precision;
    /// assert_eq!(Precision::parse_flag("--precision", "df64").unwrap(), Precision::Df64);
    /// let e = Precision::parse_flag("--precision", "f16").unwrap_err();
    /// assert_eq!(e.to_string(), "--precision f16: possible values: f32, f64, df64");
    /// ```
    fn parse_flag(flag_name: &str, value: &str) -> Result<Self, InputError> {
        Self::from_name(value).ok_or_else(|| {
            flag(
                flag_name,
                value,
                &format!("possible values: {}", Self::names()),
            )
        })
    }
}
