//! `wildlight train --config` and `--print-config` from the outside: the
//! printed configuration reads back as the same configuration, a file may
//! give only the keys it changes, and a bad file fails with its path and
//! the key named.

mod common;

use common::{path_arg, run, run_ok};

/// `train --print-config` with `args`, which must succeed; its stdout.
fn printed(args: &[&str]) -> String {
    let mut all = vec!["train", "--print-config"];
    all.extend_from_slice(args);
    run_ok(&all)
}

/// The value of `key` in `[table]` of a printed configuration (the line's
/// text after `key = `).
fn value_in<'a>(toml: &'a str, table: &str, key: &str) -> Option<&'a str> {
    let start = toml.find(&format!("\n[{table}]\n"))?;
    toml[start + 1..]
        .lines()
        .skip(1)
        .take_while(|l| !l.starts_with('['))
        .find_map(|l| l.strip_prefix(&format!("{key} = ")))
}

#[test]
fn the_printed_configuration_reads_back_unchanged() {
    let first = printed(&["--iters", "7", "--seed", "3"]);
    assert!(first.starts_with("# wildlight train"), "{first}");
    assert!(first.contains("\niters = 7\n") && first.contains("seed = 3\n"));
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("my.toml");
    std::fs::write(&file, &first).unwrap();
    assert_eq!(printed(&["--config", path_arg(&file)]), first);
}

#[test]
fn a_file_may_give_some_keys_of_a_field_table() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("partial.toml");
    std::fs::write(&file, "[model.ambient]\nhidden = [32]\n").unwrap();
    let toml = printed(&["--config", path_arg(&file)]);
    let defaults = printed(&[]);
    assert_eq!(value_in(&toml, "model.ambient", "hidden"), Some("[32]"));
    for key in ["levels", "log2_table_size", "finest_resolution"] {
        let (given, default) = (
            value_in(&toml, "model.ambient", key),
            value_in(&defaults, "model.ambient", key),
        );
        assert!(default.is_some(), "{key} is printed");
        assert_eq!(given, default, "{key}");
    }
}

#[test]
fn a_misspelt_key_fails_with_the_file_and_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("bad.toml");
    std::fs::write(&file, "[model.ambient]\nlevelz = 4\n").unwrap();
    let out = run(&["train", "--print-config", "--config", path_arg(&file)]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.toml") && err.contains("levelz"), "{err}");
    assert!(out.stdout.is_empty(), "nothing printed on failure");
}

#[test]
fn with_resume_the_runs_own_configuration_is_printed() {
    let dir = tempfile::tempdir().unwrap();
    let run_dir = dir.path().join("run");
    std::fs::create_dir(&run_dir).unwrap();
    // a run folder's two description files, as `train` writes them
    let own = printed(&["--iters", "9", "--seed", "4"]);
    std::fs::write(run_dir.join("config.toml"), &own).unwrap();
    std::fs::write(
        run_dir.join("run.json"),
        r#"{"data": "/nowhere/capture", "version": "0"}"#,
    )
    .unwrap();
    let out = path_arg(&run_dir);
    let resumed = printed(&["--resume", "--out", out]);
    assert!(resumed.contains("\niters = 9\n") && resumed.contains("seed = 4\n"));
    // --iters raises the run's step count and never lowers it
    let raised = printed(&["--resume", "--out", out, "--iters", "12"]);
    assert!(raised.contains("\niters = 12\n"), "{raised}");
    let kept = printed(&["--resume", "--out", out, "--iters", "5"]);
    assert!(kept.contains("\niters = 9\n"), "{kept}");
}

/// A run folder written before issue 48 names settings that were retired:
/// it still loads, with a warning that names them, and they are gone from
/// the configuration printed; a key that never was a setting still fails.
#[test]
fn a_run_folder_with_retired_settings_loads_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let run_dir = dir.path().join("run");
    std::fs::create_dir(&run_dir).unwrap();
    let old = "iters = 9\nerror_fraction = 0.0\n\n[loss]\ncolor_l2 = 0.0\n\
               binary_metallic_start = 0.4\n\n[model]\nambient_sh_bands = 4\n";
    std::fs::write(run_dir.join("config.toml"), old).unwrap();
    std::fs::write(
        run_dir.join("run.json"),
        r#"{"data": "/nowhere/capture", "version": "0"}"#,
    )
    .unwrap();
    let print_resumed = || {
        let out = run_dir.to_str().unwrap();
        run(&["train", "--print-config", "--resume", "--out", out])
    };
    let out = print_resumed();
    assert!(out.status.success(), "{out:?}");
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(
        stderr.contains(
            "config.toml: retired settings ignored: error_fraction, loss.color_l2, \
             model.ambient_sh_bands"
        ),
        "{stderr}"
    );
    assert!(!stderr.contains("turned on"), "{stderr}");
    assert!(!stdout.contains("color_l2") && !stdout.contains("ambient_sh_bands"));
    // the old name of a renamed key is read, and printed under the new one
    assert_eq!(
        value_in(&stdout, "loss", "binary_metallic_from"),
        Some("0.4")
    );

    std::fs::write(
        run_dir.join("config.toml"),
        format!("{old}colour_l2 = 1.0\n"),
    )
    .unwrap();
    let out = print_resumed();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("colour_l2") && err.contains("line 10"),
        "{err}"
    );
}

/// With a time budget and no --iters the budget plans the run (its step
/// count only bounds it); with both, the steps asked for are the bound.
#[test]
fn a_time_budget_without_iters_plans_the_run() {
    let budget = printed(&["--time-budget", "30m"]);
    assert!(budget.contains("\niters = 1000000\n"), "{budget}");
    let both = printed(&["--time-budget", "30m", "--iters", "50"]);
    assert!(both.contains("\niters = 50\n"), "{both}");
    let neither = printed(&[]);
    assert!(neither.contains("\niters = 4000\n"), "{neither}");
}
