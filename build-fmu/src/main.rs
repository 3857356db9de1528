//! `cargo run --release -p build-fmu [-- OPTIONS]`: builds the EhsvActuator library and
//! packs it with the generated modelDescription.xml and documentation into an FMI 2.0 and
//! an FMI 3.0 FMU under `<target>/fmu/`.
//!
//! Without options the archives carry the host's binary, built with plain cargo. Options
//! (platforms by FMI 3.0 name: x86_64-linux aarch64-linux x86_64-windows x86_64-darwin
//! aarch64-darwin, or FMI 2.0 folder: linux64 win64 darwin64):
//!   --target PLATFORM         also build PLATFORM by its cross route (repeatable)
//!   --all-targets             build every platform by its cross route
//!   --add-binary PLATFORM=PATH  put a library built elsewhere into the archives
//! A platform's binary comes from --add-binary, else its cross route, else the host build
//! (skipped when the host platform has another source). The cross routes are installed by
//! scripts/setup-cross.sh; on Linux x86_64 the cross route is the portable glibc 2.17 build.
//!
//! Every `*.png` in `docs/gallery/` (the paper's figures drawn through the FMU by
//! `cosim-examples/paper_figures.py`; `$EHSV_FIGURES_DIR` names another folder) goes into
//! `documentation/figures/` and is shown at the end of `documentation/index.html`.

use model_description::{
    documentation_html, enumerations_markdown, fmi2_xml, fmi3_xml, terminals_and_icons_xml,
    variables_markdown, CURRENT_STEP_CSV, LICENSE_TEXT, MODEL_IDENTIFIER,
};
use platforms::{Platform, PLATFORMS};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::{env, fs};

mod platforms;

fn main() -> ExitCode {
    match Options::parse(env::args().skip(1)).and_then(|o| run(&o)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("build-fmu: {message}");
            ExitCode::FAILURE
        }
    }
}

#[derive(Debug, Default, PartialEq)]
struct Options {
    /// Platforms to build by their cross route, in table order, each once.
    targets: Vec<&'static Platform>,
    /// Libraries built elsewhere.
    added: Vec<(&'static Platform, PathBuf)>,
}

const USAGE: &str = "usage: cargo run --release -p build-fmu -- [--target PLATFORM]... \
[--all-targets] [--add-binary PLATFORM=PATH]...";

impl Options {
    fn parse(mut args: impl Iterator<Item = String>) -> Result<Options, String> {
        let mut options = Options::default();
        let mut targets = vec![];
        while let Some(arg) = args.next() {
            let mut value = || args.next().ok_or(format!("{arg} needs a value\n{USAGE}"));
            match arg.as_str() {
                "--target" => targets.push(platforms::platform(&value()?)?),
                "--all-targets" => targets.extend(PLATFORMS),
                "--add-binary" => {
                    let value = value()?;
                    let (name, path) = value
                        .split_once('=')
                        .ok_or(format!("--add-binary {value}: expected PLATFORM=PATH"))?;
                    options.added.push((platforms::platform(name)?, PathBuf::from(path)));
                }
                "-h" | "--help" => return Err(USAGE.to_string()),
                other => return Err(format!("unknown argument {other:?}\n{USAGE}")),
            }
        }
        options.targets = PLATFORMS.iter().filter(|p| targets.contains(p)).collect();
        Ok(options)
    }
}

/// Where each platform's library comes from.
fn sources(options: &Options, host: Option<&'static Platform>) -> Vec<(&'static Platform, Source)> {
    let mut sources: Vec<(&'static Platform, Source)> = vec![];
    for (platform, path) in &options.added {
        sources.retain(|(p, _)| p != platform);
        sources.push((platform, Source::File(path.clone())));
    }
    let has = |sources: &[(&Platform, Source)], p: &Platform| sources.iter().any(|(q, _)| *q == p);
    for &platform in &options.targets {
        if !has(&sources, platform) {
            sources.push((platform, Source::Cross));
        }
    }
    if let Some(host) = host {
        if !has(&sources, host) {
            sources.push((host, Source::Host));
        }
    }
    sources.sort_by_key(|(p, _)| PLATFORMS.iter().position(|q| q == *p));
    sources
}

#[derive(Debug, PartialEq)]
enum Source {
    Host,
    Cross,
    File(PathBuf),
}

fn run(options: &Options) -> Result<(), String> {
    let workspace = workspace_root();
    let target = target_dir(&workspace);
    // The host build is optional when every binary comes from elsewhere.
    let host = platforms::host();
    let sources = sources(options, host.as_ref().ok().copied());
    if sources.is_empty() {
        return Err(host.err().unwrap_or_default());
    }
    let mut binaries = vec![];
    for (platform, source) in sources {
        let started = std::time::Instant::now();
        let path = match source {
            Source::Host => platforms::build_host(&workspace, &target)?,
            Source::Cross => platform.build(&workspace, &target)?,
            Source::File(path) => path,
        };
        let bytes = fs::read(&path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        let seconds = started.elapsed().as_secs_f64();
        println!("{}: {} ({} bytes, {seconds:.1} s)", platform.fmi3, path.display(), bytes.len());
        binaries.push((platform, bytes));
    }

    let readme = format!(
        "# {MODEL_IDENTIFIER} variables\n\n{}\n{}",
        variables_markdown(),
        enumerations_markdown()
    );
    let figures = figures(&workspace)?;
    let names: Vec<String> = figures.iter().map(|(name, _)| name.clone()).collect();
    let index_html = documentation_html(&names);
    let out_dir = target.join("fmu");
    fs::create_dir_all(&out_dir)
        .map_err(|e| format!("cannot create {}: {e}", out_dir.display()))?;
    let terminals = terminals_and_icons_xml();
    for (version, xml) in [("fmi2", fmi2_xml()), ("fmi3", fmi3_xml())] {
        let mut entries: Vec<(String, &[u8])> = vec![
            ("modelDescription.xml".into(), xml.as_bytes()),
            ("documentation/index.html".into(), index_html.as_bytes()),
            ("documentation/README.md".into(), readme.as_bytes()),
            ("documentation/current_step.csv".into(), CURRENT_STEP_CSV.as_bytes()),
            ("documentation/licenses/license.txt".into(), LICENSE_TEXT.as_bytes()),
            ("model.png".into(), ICON),
        ];
        if version == "fmi3" {
            // FMI 3.0 keeps the icon with the terminals.
            entries.push(("terminalsAndIcons/terminalsAndIcons.xml".into(), terminals.as_bytes()));
            entries.push(("terminalsAndIcons/icon.png".into(), ICON));
        }
        for (name, bytes) in &figures {
            entries.push((format!("documentation/figures/{name}"), bytes));
        }
        for (platform, bytes) in &binaries {
            let folder = if version == "fmi2" { platform.fmi2 } else { Some(platform.fmi3) };
            if let Some(folder) = folder {
                let name = platform.library_name(MODEL_IDENTIFIER);
                entries.push((format!("binaries/{folder}/{name}"), bytes));
            }
        }
        let fmu = out_dir.join(format!("{MODEL_IDENTIFIER}-{version}.fmu"));
        write_zip(&fmu, &entries).map_err(|e| format!("cannot write {}: {e}", fmu.display()))?;
        let size = fs::metadata(&fmu).map(|m| m.len()).unwrap_or(0);
        println!("wrote {} ({size} bytes)", fmu.display());
        for (name, bytes) in &entries {
            println!("  {name} ({} bytes)", bytes.len());
        }
    }
    Ok(())
}

/// The FMU's icon, drawn by modelDescription/icon/make_icon.py.
const ICON: &[u8] = include_bytes!("../../modelDescription/icon/model.png");

/// The paper's figures (name, bytes), sorted by name; none if the folder is missing.
fn figures(workspace: &Path) -> Result<Vec<(String, Vec<u8>)>, String> {
    let dir = env::var_os("EHSV_FIGURES_DIR")
        .map_or_else(|| workspace.join("docs").join("gallery"), PathBuf::from);
    let Ok(entries) = fs::read_dir(&dir) else { return Ok(vec![]) };
    let mut figures = vec![];
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.ends_with(".png") {
            let bytes = fs::read(entry.path())
                .map_err(|e| format!("cannot read {}: {e}", entry.path().display()))?;
            figures.push((name, bytes));
        }
    }
    figures.sort();
    Ok(figures)
}

/// build-fmu lives one level below the workspace root.
fn workspace_root() -> PathBuf {
    let manifest_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    manifest_dir.parent().expect("build-fmu is inside the workspace").to_path_buf()
}

/// CARGO_TARGET_DIR if set (relative to the workspace, where we run cargo), else `<workspace>/target`.
fn target_dir(workspace: &Path) -> PathBuf {
    match env::var_os("CARGO_TARGET_DIR") {
        Some(dir) => workspace.join(dir),
        None => workspace.join("target"),
    }
}

fn write_zip(path: &Path, entries: &[(String, &[u8])]) -> zip::result::ZipResult<()> {
    let mut zip = zip::ZipWriter::new(fs::File::create(path)?);
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated);
    for (name, bytes) in entries {
        zip.start_file(name.as_str(), options)?;
        zip.write_all(bytes)?;
    }
    zip.finish()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(args: &[&str]) -> Result<Options, String> {
        Options::parse(args.iter().map(|a| a.to_string()))
    }

    #[test]
    fn plain_command_is_the_host_build_only() {
        let host = platforms::platform("x86_64-linux").unwrap();
        assert_eq!(sources(&parse(&[]).unwrap(), Some(host)), [(host, Source::Host)]);
    }

    #[test]
    fn targets_replace_the_host_build_and_added_binaries_replace_targets() {
        let options = parse(&[
            "--all-targets",
            "--target",
            "win64",
            "--add-binary",
            "x86_64-darwin=/m.dylib",
        ])
        .unwrap();
        assert_eq!(options.targets.len(), PLATFORMS.len(), "each platform once");
        let host = platforms::platform("x86_64-linux").unwrap();
        let got = sources(&options, Some(host));
        let names: Vec<(&str, &Source)> = got.iter().map(|(p, s)| (p.fmi3, s)).collect();
        assert_eq!(
            names,
            [
                ("x86_64-linux", &Source::Cross),
                ("aarch64-linux", &Source::Cross),
                ("x86_64-windows", &Source::Cross),
                ("x86_64-darwin", &Source::File("/m.dylib".into())),
                ("aarch64-darwin", &Source::Cross),
            ]
        );
    }

    #[test]
    fn bad_arguments_are_refused_with_the_usage() {
        assert!(parse(&["--target"]).unwrap_err().contains("needs a value"));
        assert!(parse(&["--target", "sparc-solaris"]).unwrap_err().contains("x86_64-windows"));
        assert!(parse(&["--add-binary", "win64"]).unwrap_err().contains("PLATFORM=PATH"));
        assert!(parse(&["--frobnicate"]).unwrap_err().contains("usage"));
    }
}
