//! Command-line parsing (unit tests of the private `cli` module): negative numbers reach every number, point and vector flag of every
//! command (issue 19), and the flags and positional arguments after them still parse.

use super::{BenchCommand, Cli, Command};
use clap::error::ErrorKind;
use clap::{ArgMatches, CommandFactory, Parser};

/// Every command without subcommands, with the words that reach it.
fn leaves(cmd: &clap::Command, path: Vec<String>, out: &mut Vec<(Vec<String>, clap::Command)>) {
    if cmd.has_subcommands() {
        for sub in cmd.get_subcommands() {
            let mut p = path.clone();
            p.push(sub.get_name().to_string());
            leaves(sub, p, out);
        }
    } else {
        out.push((path, cmd.clone()));
    }
}

/// The matches of the innermost subcommand.
fn leaf_matches(m: &ArgMatches) -> &ArgMatches {
    match m.subcommand() {
        Some((_, sub)) => leaf_matches(sub),
        None => m,
    }
}

fn raw(m: &ArgMatches, id: &str) -> Vec<String> {
    m.get_raw(id).map(|v| v.map(|s| s.to_string_lossy().into_owned()).collect()).unwrap_or_default()
}

fn argv(path: &[String], rest: &[&str]) -> Vec<String> {
    let mut v = vec!["propsim".to_string()];
    v.extend(path.iter().cloned());
    v.extend(rest.iter().map(|s| s.to_string()));
    v
}

/// Walks every flag of every command that takes a value; those whose value is a number or a
/// list of numbers (their parser refuses a word and takes one of the shapes below) are given
/// the same shape negated, followed by another flag and the positional argument.
#[test]
fn every_numeric_flag_takes_negative_values() {
    let mut root = Cli::command();
    root.build(); // Copies the global flags (--threads) into every subcommand.
    let mut commands = Vec::new();
    leaves(&root, Vec::new(), &mut commands);
    assert!(commands.len() >= 9, "{} commands", commands.len());
    let mut tested = Vec::new();
    for (path, cmd) in &commands {
        let positional = cmd.get_positionals().next().map(|a| a.get_id().to_string());
        for arg in cmd.get_arguments() {
            if arg.is_positional() || !arg.get_action().takes_values() {
                continue;
            }
            let flag = match (arg.get_long(), arg.get_short()) {
                (Some(l), _) => format!("--{l}"),
                (None, Some(s)) => format!("-{s}"),
                (None, None) => continue,
            };
            // The positional argument too, as some commands require one.
            let parses = |value: &str| Cli::try_parse_from(argv(path, &[&flag, value, "given.toml"])).is_ok();
            if parses("abc") {
                continue; // a name, a path or free text
            }
            let Some(shape) = ["1.5", "1", "1,2", "1,2,3"].into_iter().find(|s| parses(s)) else {
                continue; // a choice among words
            };
            let negative: Vec<String> = shape.split(',').map(|c| format!("-{c}")).collect();
            let negative = negative.join(",");
            let id = arg.get_id().as_str();
            let mut rest = vec![flag.as_str(), negative.as_str()];
            if id != "threads" {
                rest.extend(["--threads", "3"]);
            }
            if positional.is_some() {
                rest.push("given.toml");
            }
            let words = argv(path, &rest);
            match Cli::command().try_get_matches_from(&words) {
                Ok(m) => {
                    let m = leaf_matches(&m);
                    assert_eq!(raw(m, id), [negative.as_str()], "{words:?}");
                    if id != "threads" {
                        assert_eq!(raw(m, "threads"), ["3"], "{words:?}: the next flag");
                    }
                    if let Some(p) = &positional {
                        assert_eq!(raw(m, p), ["given.toml"], "{words:?}: the positional argument");
                    }
                }
                // Parsed, then refused by the flag's own check (e.g. a count below zero).
                Err(e) => {
                    let text = e.to_string();
                    assert!(
                        matches!(e.kind(), ErrorKind::ValueValidation | ErrorKind::InvalidValue)
                            && text.contains(&flag)
                            && text.contains(&negative),
                        "{words:?}: {:?} {text}",
                        e.kind()
                    );
                }
            }
            tested.push(format!("{} {flag}", path.join(" ")));
        }
    }
    // The walk saw the flags of the issue (so that it cannot pass by skipping everything).
    for expected in [
        "acoustic --receiver",
        "acoustic --source",
        "acoustic --temperature-c",
        "render --eye",
        "render --target",
        "render --up",
        "rf --grid-min",
        "rf --tx",
        "info --point",
        "info --threads",
        "bench trace --ray-count",
        "bench render --spp",
        "bench acoustic --rays",
        "bench rf --cell-m",
        "run --seed",
    ] {
        assert!(tested.iter().any(|t| t == expected), "{expected} not walked; walked: {tested:?}");
    }
}

fn parse(words: &[&str]) -> Command {
    let mut v = vec!["propsim"];
    v.extend(words);
    match Cli::try_parse_from(&v) {
        Ok(cli) => cli.command,
        Err(e) => panic!("{words:?}: {e}"),
    }
}

#[test]
fn negative_values_of_the_issue_parse_to_their_numbers() {
    let Command::Acoustic(a) = parse(&[
        "acoustic",
        "room.toml",
        "--receiver",
        "-0.993,1.426,1.23",
        "--source",
        "-1,2,3",
        "--temperature-c",
        "-5",
        "--rays",
        "10",
    ]) else {
        panic!("not acoustic")
    };
    assert_eq!(a.options.receivers, [[-0.993, 1.426, 1.23]]);
    assert_eq!(a.options.sources, [[-1.0, 2.0, 3.0]]);
    assert_eq!(a.options.temperature_c, Some(-5.0));
    assert_eq!(a.options.rays, Some(10));
    assert_eq!(a.scene.to_str(), Some("room.toml"));

    // A negative value, then the positional scene.
    let Command::Acoustic(a) = parse(&["acoustic", "--receiver", "-1,2,1.2", "--rays", "10", "room.toml"])
    else {
        panic!("not acoustic")
    };
    assert_eq!(
        (a.options.receivers, a.options.rays, a.scene.to_str()),
        (vec![[-1.0, 2.0, 1.2]], Some(10), Some("room.toml"))
    );

    let Command::Render(r) =
        parse(&["render", "--eye", "-4,0,1", "--target", "0,-2.5,-1e-1", "--fov-deg", "-3"])
    else {
        panic!("not render")
    };
    assert_eq!(
        (r.options.eye, r.options.target, r.options.fov_deg),
        (Some([-4.0, 0.0, 1.0]), Some([0.0, -2.5, -0.1]), Some(-3.0))
    );

    let Command::Rf(f) = parse(&[
        "rf",
        "street.toml",
        "--grid-min",
        "-90,-60",
        "--grid-max",
        "-10,-5",
        "--tx-power-dbm",
        "-7.5",
    ]) else {
        panic!("not rf")
    };
    assert_eq!(
        (f.options.grid_min, f.options.grid_max, f.options.tx_power_dbm),
        (Some([-90.0, -60.0]), Some([-10.0, -5.0]), Some(-7.5))
    );

    let Command::Info(i) = parse(&["info", "--point", "-1,2,1.2", "--point", "3,-4,-5", "--json"]) else {
        panic!("not info")
    };
    assert_eq!(i.points, [[-1.0, 2.0, 1.2], [3.0, -4.0, -5.0]]);
    assert!(i.json);

    let Command::Bench(BenchCommand::Rf(b)) = parse(&["bench", "rf", "--cell-m", "-2"]) else {
        panic!("not bench rf")
    };
    assert_eq!(b.cell_m, -2.0);

    // A negative thread count is a bad value, not an unknown argument.
    let e = Cli::try_parse_from(["propsim", "--threads", "-1", "info"]).unwrap_err();
    assert_eq!(e.kind(), ErrorKind::ValueValidation, "{e}");
}

#[test]
fn a_flag_missing_its_value_is_not_swallowed_as_a_number() {
    // A plain-number flag does not take the next flag as its value.
    let e = Cli::try_parse_from(["propsim", "rf", "s.toml", "--freq-ghz", "--rays", "3"]).unwrap_err();
    assert_eq!(e.kind(), ErrorKind::InvalidValue, "{e}");
    assert!(e.to_string().contains("--freq-ghz"), "{e}");
    // A word that only starts like a number is still refused as an unknown argument.
    let e = Cli::try_parse_from(["propsim", "acoustic", "--temperature-c", "-x"]).unwrap_err();
    assert_eq!(e.kind(), ErrorKind::UnknownArgument, "{e}");
}
