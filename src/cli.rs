//! What the command-line programs (`reducem`, `pipeline`) share besides their exit codes
//! ([`crate::exit_code`]).

use std::path::Path;

use crate::exit_code::UsageError;

/// Refuses an input that must be mapped (a ReduceM file) when it is standard input (`-`) or not
/// a regular file: a pipe maps as empty, and would be reported as a truncated file.
pub fn check_mappable(path: &Path) -> Result<(), UsageError> {
    let stream = path.as_os_str() == "-"
        || std::fs::metadata(path).is_ok_and(|metadata| !metadata.is_file() && !metadata.is_dir());
    match stream {
        true => Err(UsageError(format!(
            "{}: a ReduceM file is mapped, so it must be a regular file, not standard input, a \
             pipe or a device (save the stream to a file first)",
            path.display()
        ))),
        false => Ok(()),
    }
}

/// Every argument of `command`'s subcommands, and every value of an enumerated one, that
/// `--help` would list without a description, as `"program subcommand argument [value]"`.
/// Both programs' tests require it to be empty.
pub fn undescribed_arguments(command: &clap::Command) -> Vec<String> {
    let program = command.get_name();
    let mut undescribed = Vec::new();
    for subcommand in command.get_subcommands() {
        for argument in subcommand.get_arguments() {
            let name = format!("{program} {} {}", subcommand.get_name(), argument.get_id());
            if argument.get_help().is_none() {
                undescribed.push(name.clone());
            }
            let enumerated = argument.get_action().takes_values();
            let values = enumerated.then(|| argument.get_value_parser().possible_values());
            for value in values.into_iter().flatten().flatten() {
                if value.get_help().is_none() {
                    undescribed.push(format!("{name} {}", value.get_name()));
                }
            }
        }
    }
    undescribed
}

/// The parsed command line, or the exit code to end with once clap has printed why not: 0
/// after `--help` or `--version`, 64 (usage) for arguments it refuses.
pub fn parse_or_exit<C: clap::Parser>() -> Result<C, std::process::ExitCode> {
    C::try_parse().map_err(|error| {
        let code = if error.use_stderr() {
            crate::exit_code::USAGE
        } else {
            crate::exit_code::SUCCESS
        };
        let _ = error.print();
        std::process::ExitCode::from(code)
    })
}
