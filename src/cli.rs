//! What the command-line programs (`reducem`, `pipeline`) share besides their exit codes
//! ([`crate::exit_code`]).

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
