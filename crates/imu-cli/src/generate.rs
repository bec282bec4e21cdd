//! Man pages (clap_mangen) and shell completions (clap_complete) of any tool, from its clap
//! command: `TOOL --generate man DIR` writes `TOOL.1` and one `TOOL-SUB.1` per subcommand,
//! `TOOL --generate bash|zsh|fish|elvish|powershell DIR` the completion script. Every tool
//! that uses [`crate::main`] answers this hidden flag; `scripts/install` calls it, so the
//! pages and scripts are generated at install time and never committed.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use clap::CommandFactory;
use clap_complete::Shell;

/// The hidden flag [`handle`] answers.
pub const FLAG: &str = "--generate";

/// What `--generate` can write.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Artifact {
    /// Roff man pages, section 1.
    Man,
    /// A completion script for this shell.
    Completion(Shell),
}

impl std::str::FromStr for Artifact {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        if s == "man" {
            return Ok(Artifact::Man);
        }
        <Shell as clap::ValueEnum>::from_str(s, true)
            .map(Artifact::Completion)
            .map_err(|_| format!("{FLAG} {s}: write man, bash, zsh, fish, elvish or powershell"))
    }
}

/// Writes `what` for `cmd` into `dir` (created if missing) and returns the files written.
pub fn write(mut cmd: clap::Command, what: Artifact, dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let name = cmd.get_name().to_string();
    match what {
        Artifact::Man => {
            cmd.build();
            let mut written = Vec::new();
            write_man(&cmd, &name, dir, &mut written)?;
            Ok(written)
        }
        Artifact::Completion(shell) => {
            let path =
                clap_complete::generate_to(shell, &mut cmd, &name, dir).with_context(|| {
                    format!("writing the {shell} completion into {}", dir.display())
                })?;
            Ok(vec![path])
        }
    }
}

/// `page` is the man page name: the tool's, then `-sub` for each level of subcommand.
fn write_man(
    cmd: &clap::Command,
    page: &str,
    dir: &Path,
    written: &mut Vec<PathBuf>,
) -> anyhow::Result<()> {
    let path = dir.join(format!("{page}.1"));
    let mut roff = Vec::new();
    clap_mangen::Man::new(cmd.clone())
        .title(page)
        .render(&mut roff)
        .with_context(|| format!("rendering the man page {page}"))?;
    std::fs::write(&path, roff).with_context(|| format!("writing {}", path.display()))?;
    written.push(path);
    for sub in cmd.get_subcommands().filter(|s| !s.is_hide_set()) {
        if sub.get_name() == "help" {
            continue;
        }
        write_man(sub, &format!("{page}-{}", sub.get_name()), dir, written)?;
    }
    Ok(())
}

/// Answers `TOOL --generate WHAT DIR` for the command `C` (printing the files written) and
/// returns the exit code; `None` when `args` are not a `--generate` call.
pub fn handle<C: CommandFactory>(args: &[OsString]) -> Option<ExitCode> {
    if args.get(1).map(OsString::as_os_str) != Some(FLAG.as_ref()) {
        return None;
    }
    let cmd = C::command();
    let name = cmd.get_name().to_string();
    let (Some(what), Some(dir), None) = (args.get(2), args.get(3), args.get(4)) else {
        eprintln!("{name}: error: usage: {name} {FLAG} man|bash|zsh|fish|elvish|powershell DIR");
        return Some(ExitCode::from(crate::exit::EXIT_USAGE));
    };
    let what = match what.to_string_lossy().parse::<Artifact>() {
        Ok(w) => w,
        Err(e) => {
            eprintln!("{name}: error: {e}");
            return Some(ExitCode::from(crate::exit::EXIT_USAGE));
        }
    };
    Some(match write(cmd, what, Path::new(dir)) {
        Ok(files) => {
            for f in files {
                println!("{}", f.display());
            }
            ExitCode::SUCCESS
        }
        Err(e) => crate::exit::report(&name, &e),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tool with one subcommand.
    #[derive(Debug, clap::Parser)]
    #[command(name = "demo-tool", about = "A demo")]
    struct Demo {
        #[command(subcommand)]
        cmd: Sub,
    }

    #[derive(Debug, clap::Subcommand)]
    enum Sub {
        /// Does a thing.
        Thing {
            /// How fast.
            #[arg(long)]
            speed: u32,
        },
    }

    #[test]
    fn man_pages_for_the_tool_and_each_subcommand_and_completions() {
        let dir = tempfile::tempdir().unwrap();
        let os = |v: &[&str]| v.iter().map(OsString::from).collect::<Vec<_>>();
        let d = dir.path().to_str().unwrap();
        let code = handle::<Demo>(&os(&["demo-tool", FLAG, "man", d]));
        assert_eq!(code, Some(ExitCode::SUCCESS));
        let top = std::fs::read_to_string(dir.path().join("demo-tool.1")).unwrap();
        assert!(
            top.contains(".TH demo-tool 1") && top.contains("A demo"),
            "{top}"
        );
        let sub = std::fs::read_to_string(dir.path().join("demo-tool-thing.1")).unwrap();
        assert!(sub.contains("\\-\\-speed"), "{sub}");
        assert!(!dir.path().join("demo-tool-help.1").exists());
        for shell in ["bash", "zsh", "fish"] {
            assert_eq!(
                handle::<Demo>(&os(&["demo-tool", FLAG, shell, d])),
                Some(ExitCode::SUCCESS)
            );
        }
        let bash = std::fs::read_to_string(dir.path().join("demo-tool.bash")).unwrap();
        assert!(bash.contains("--speed"));
        assert!(dir.path().join("_demo-tool").exists());
        assert!(dir.path().join("demo-tool.fish").exists());
        assert_eq!(
            handle::<Demo>(&os(&["demo-tool", FLAG, "nroff", d])),
            Some(ExitCode::from(crate::exit::EXIT_USAGE))
        );
        assert_eq!(handle::<Demo>(&os(&["demo-tool", "thing"])), None);
    }
}
