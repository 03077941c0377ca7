//! Options spelled by name on the command line and in Python (`--crossover`, `--restarts`,
//! `--local-cost`): one table of (value, name) per option, read both ways here.

/// The name of `value` in `table` (the table lists every value).
pub(crate) fn name_of<T: Copy + PartialEq>(table: &[(T, &'static str)], value: T) -> &'static str {
    table
        .iter()
        .find(|(v, _)| *v == value)
        .map_or("", |(_, n)| n)
}

/// The value named `s` in `table`, or one line naming the option (`what`) and listing the
/// names.
pub(crate) fn parse_name<T: Copy>(
    table: &[(T, &'static str)],
    what: &str,
    s: &str,
) -> Result<T, String> {
    table
        .iter()
        .find(|(_, n)| *n == s)
        .map(|(v, _)| *v)
        .ok_or_else(|| {
            let names: Vec<&str> = table.iter().map(|(_, n)| *n).collect();
            format!(
                "unknown {what} `{s}` (expected one of: {})",
                names.join(", ")
            )
        })
}
