//! `cargo run --release -p build-fmu`: builds the EhsvActuator cdylib for the host and packs
//! it with the generated modelDescription.xml into an FMI 2.0 and an FMI 3.0 FMU under
//! `<target>/fmu/`.

use model_description::{
    enumerations_markdown, fmi2_xml, fmi3_xml, variables_markdown, MODEL_IDENTIFIER,
};
use std::env::consts::{ARCH, DLL_PREFIX, DLL_SUFFIX, OS};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};
use std::{env, fs};

/// The package and `[lib] name` of the FMU crate (fmu-src/Cargo.toml).
const FMU_PACKAGE: &str = "ehsv-actuator";
const FMU_LIBRARY: &str = "ehsv_actuator";

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("build-fmu: {message}");
            ExitCode::FAILURE
        }
    }
}

fn run() -> Result<(), String> {
    let workspace = workspace_root();
    let target = target_dir(&workspace);
    build_library(&workspace)?;

    let library_path =
        target.join("release").join(format!("{DLL_PREFIX}{FMU_LIBRARY}{DLL_SUFFIX}"));
    let library = fs::read(&library_path)
        .map_err(|e| format!("cannot read {}: {e}", library_path.display()))?;
    let readme = format!(
        "# {MODEL_IDENTIFIER} variables\n\n{}\n{}",
        variables_markdown(),
        enumerations_markdown()
    );
    let index_html = documentation_html();
    // Inside the FMU the library is named after the modelIdentifier.
    let library_name = format!("{MODEL_IDENTIFIER}{DLL_SUFFIX}");

    let out_dir = target.join("fmu");
    fs::create_dir_all(&out_dir)
        .map_err(|e| format!("cannot create {}: {e}", out_dir.display()))?;
    for (version, xml, platform) in
        [("fmi2", fmi2_xml(), fmi2_platform()?), ("fmi3", fmi3_xml(), fmi3_platform()?)]
    {
        let binary = format!("binaries/{platform}/{library_name}");
        let entries: [(&str, &[u8]); 4] = [
            ("modelDescription.xml", xml.as_bytes()),
            (&binary, &library),
            ("documentation/index.html", index_html.as_bytes()),
            ("documentation/README.md", readme.as_bytes()),
        ];
        let fmu = out_dir.join(format!("{MODEL_IDENTIFIER}-{version}.fmu"));
        write_zip(&fmu, &entries).map_err(|e| format!("cannot write {}: {e}", fmu.display()))?;
        let size = fs::metadata(&fmu).map(|m| m.len()).unwrap_or(0);
        println!("wrote {} ({size} bytes)", fmu.display());
        for (name, bytes) in entries {
            println!("  {name} ({} bytes)", bytes.len());
        }
    }
    Ok(())
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

/// `cargo run` sets CARGO to the cargo that runs us; fall back to `cargo` on PATH.
fn build_library(workspace: &Path) -> Result<(), String> {
    let cargo = env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let status = Command::new(&cargo)
        .args(["build", "--release", "-p", FMU_PACKAGE])
        .current_dir(workspace)
        .status()
        .map_err(|e| format!("cannot run {}: {e}", Path::new(&cargo).display()))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("cargo build --release -p {FMU_PACKAGE} failed ({status})"))
    }
}

/// FMI 2.0 platform folder names (spec section 2.1: win32/win64/linux32/linux64/darwin32/darwin64).
fn fmi2_platform() -> Result<String, String> {
    let os = match OS {
        "windows" => "win",
        "linux" => "linux",
        "macos" => "darwin",
        other => return Err(format!("FMI 2.0 has no platform folder for OS {other}")),
    };
    let bits = if cfg!(target_pointer_width = "64") { "64" } else { "32" };
    Ok(format!("{os}{bits}"))
}

/// FMI 3.0 platform tuple `<arch>-<os>` (spec section 2.5.1.4).
fn fmi3_platform() -> Result<String, String> {
    let arch = match ARCH {
        "x86_64" | "aarch64" | "x86" | "riscv32" | "riscv64" => ARCH,
        "arm" => "aarch32",
        "powerpc" => "ppc32",
        "powerpc64" => "ppc64",
        other => return Err(format!("FMI 3.0 has no architecture name for {other}")),
    };
    let os = match OS {
        "windows" | "linux" => OS,
        "macos" => "darwin",
        other => return Err(format!("FMI 3.0 has no platform name for OS {other}")),
    };
    Ok(format!("{arch}-{os}"))
}

fn write_zip(path: &Path, entries: &[(&str, &[u8])]) -> zip::result::ZipResult<()> {
    let mut zip = zip::ZipWriter::new(fs::File::create(path)?);
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated);
    for (name, bytes) in entries {
        zip.start_file(*name, options)?;
        zip.write_all(bytes)?;
    }
    zip.finish()?;
    Ok(())
}

/// documentation/index.html (the FMI entry point): the variable table as HTML.
fn documentation_html() -> String {
    let mut rows = variables_markdown().lines().map(markdown_cells).collect::<Vec<_>>();
    rows.remove(1); // the |---| separator row
    let mut html = format!(
        "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{MODEL_IDENTIFIER}</title></head><body>\n\
         <h1>{MODEL_IDENTIFIER}</h1>\n<p>{}</p>\n<table border=\"1\">\n",
        escape(model_description::MODEL_DESCRIPTION)
    );
    for (i, row) in rows.iter().enumerate() {
        let tag = if i == 0 { "th" } else { "td" };
        html += "<tr>";
        for cell in row {
            html += &format!("<{tag}>{}</{tag}>", code_spans(&escape(cell)));
        }
        html += "</tr>\n";
    }
    html += &format!(
        "</table>\n<h2>Enumerations</h2>\n<pre>{}</pre>\n</body></html>\n",
        escape(&enumerations_markdown())
    );
    html
}

/// Cells of one Markdown table row; `\|` is a literal pipe.
fn markdown_cells(line: &str) -> Vec<String> {
    let inner = line.trim().strip_prefix('|').unwrap_or(line);
    let inner = inner.strip_suffix('|').unwrap_or(inner);
    let mut cells = vec![String::new()];
    let mut chars = inner.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '\\' if chars.peek() == Some(&'|') => {
                cells.last_mut().unwrap().push(chars.next().unwrap())
            }
            '|' => cells.push(String::new()),
            c => cells.last_mut().unwrap().push(c),
        }
    }
    cells.iter().map(|c| c.trim().to_string()).collect()
}

/// `code` -> <code>code</code>
fn code_spans(text: &str) -> String {
    text.split('`')
        .enumerate()
        .map(|(i, part)| if i % 2 == 1 { format!("<code>{part}</code>") } else { part.to_string() })
        .collect()
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn markdown_cells_keep_empty_cells_and_escaped_pipes() {
        assert_eq!(markdown_cells("| 0 | `time` |  | a \\| b |"), ["0", "`time`", "", "a | b"]);
    }

    #[test]
    fn documentation_has_a_row_per_variable() {
        let html = documentation_html();
        let variables = variables_markdown().lines().count() - 2; // minus header and separator
        assert_eq!(html.matches("<tr>").count(), 1 + variables);
        assert!(html.contains("<code>coil.L</code>"));
    }

    #[test]
    fn host_platform_names_exist() {
        assert!(fmi2_platform().unwrap().ends_with("64") || cfg!(target_pointer_width = "32"));
        assert!(fmi3_platform().unwrap().contains('-'));
    }
}
