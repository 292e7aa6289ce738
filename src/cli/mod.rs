//! Command-line interface of the `mavtables` binary.

/// Options understood on the command line.
#[derive(Debug, Default, Clone, PartialEq, Eq)]
pub struct Options {
    /// Path given with `--config`.
    pub config: Option<String>,
    /// Log level 0..=3 given with `--loglevel`.
    pub loglevel: u8,
}

/// Parses the command line (without the program name). Minimal until the CLI issue.
pub fn parse<I: IntoIterator<Item = String>>(args: I) -> Result<Options, String> {
    let mut opts = Options::default();
    let mut it = args.into_iter();
    while let Some(arg) = it.next() {
        if let Some(v) = arg.strip_prefix("--config=") {
            opts.config = Some(v.to_string());
        } else if arg == "--config" {
            opts.config = Some(
                it.next()
                    .ok_or("the required argument for option '--config' is missing")?,
            );
        } else if arg == "--loglevel" {
            let v = it
                .next()
                .ok_or("the required argument for option '--loglevel' is missing")?;
            opts.loglevel = v
                .parse::<u32>()
                .map(|n| n.min(3) as u8)
                .map_err(|_| format!("the argument ('{v}') for option '--loglevel' is invalid"))?;
        } else if arg.starts_with("--") {
            return Err(format!("unrecognised option '{arg}'"));
        }
    }
    Ok(opts)
}
