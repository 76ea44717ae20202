//! `cargo xtask size`: flash and static RAM of the release firmware, from
//! the ELF's section headers, and its biggest symbols.

use std::collections::BTreeSet;
use std::fmt::Write as _;
use std::path::Path;

use object::{Object, ObjectSection, ObjectSymbol, SectionFlags, SymbolKind, SymbolSection};

use crate::target::{Build, grouped, rustc_version, write_report};

/// Where the report is always written (relative to the workspace root).
pub const REPORT: &str = "target/size.md";

/// Sections stored in flash (`.data` is copied from flash to RAM at reset).
const FLASH: [&str; 4] = [".vector_table", ".text", ".rodata", ".data"];
/// Sections that occupy RAM before the stack.
const RAM: [&str; 3] = [".data", ".bss", ".uninit"];
/// Symbols listed per build.
const TOP_SYMBOLS: usize = 15;

/// The boards: name and whether it is the default feature.
const BOARDS: [(&str, bool); 2] = [("board-qemu", true), ("board-blackpill", false)];

/// Sizes of one ELF.
#[derive(Debug, Clone, PartialEq)]
pub struct Sizes {
    /// Size of each section of [`FLASH`] and [`RAM`], in that order, bytes.
    pub sections: Vec<(&'static str, u64)>,
    /// `.vector_table + .text + .rodata + .data`, bytes.
    pub flash: u64,
    /// `.data + .bss + .uninit`, bytes.
    pub ram: u64,
    /// Other allocated sections of non-zero size (expected: none).
    pub other: Vec<(String, u64)>,
    /// The biggest symbols: size, section, demangled name.
    pub symbols: Vec<(u64, String, String)>,
}

/// Reads the sizes from an ELF's section headers and symbol table.
pub fn analyse(elf: &Path) -> Result<Sizes, String> {
    let data = std::fs::read(elf).map_err(|e| format!("read {}: {e}", elf.display()))?;
    let file = object::File::parse(&*data).map_err(|e| format!("{}: {e}", elf.display()))?;
    let size_of = |name: &str| file.section_by_name(name).map_or(0, |s| s.size());
    let sections: Vec<(&'static str, u64)> = FLASH
        .iter()
        .chain(RAM.iter().filter(|s| !FLASH.contains(s)))
        .map(|&name| (name, size_of(name)))
        .collect();
    let flash = FLASH.iter().map(|s| size_of(s)).sum();
    let ram = RAM.iter().map(|s| size_of(s)).sum();
    let other = file
        .sections()
        .filter(|s| {
            matches!(s.flags(), SectionFlags::Elf { sh_flags }
                if sh_flags & u64::from(object::elf::SHF_ALLOC) != 0)
        })
        .filter_map(|s| Some((s.name().ok()?.to_string(), s.size())))
        .filter(|(name, size)| {
            *size > 0 && !FLASH.contains(&name.as_str()) && !RAM.contains(&name.as_str())
        })
        .collect();

    let mut seen = BTreeSet::new();
    let mut symbols: Vec<(u64, String, String)> = file
        .symbols()
        .filter(|s| matches!(s.kind(), SymbolKind::Text | SymbolKind::Data) && s.size() > 0)
        // Aliases (same address and size) are listed once.
        .filter(|s| seen.insert((s.address(), s.size())))
        .map(|s| {
            let section = match s.section() {
                SymbolSection::Section(i) => file
                    .section_by_index(i)
                    .ok()
                    .and_then(|sec| sec.name().ok().map(str::to_string))
                    .unwrap_or_default(),
                _ => String::new(),
            };
            let name = s.name().unwrap_or("?");
            (
                s.size(),
                section,
                format!("{:#}", rustc_demangle::demangle(name)),
            )
        })
        .collect();
    symbols.sort_by(|a, b| b.0.cmp(&a.0).then_with(|| a.2.cmp(&b.2)));
    symbols.truncate(TOP_SYMBOLS);
    Ok(Sizes {
        sections,
        flash,
        ram,
        other,
        symbols,
    })
}

/// `bytes B (x.y KiB)`, or `bytes B` under 1 KiB.
pub fn bytes_kib(bytes: u64) -> String {
    if bytes < 1024 {
        format!("{bytes} B")
    } else {
        format!("{} B ({:.1} KiB)", grouped(bytes), bytes as f64 / 1024.0)
    }
}

/// Builds `wmr-firmware` for one board into `target/xtask/elf/<label>`.
pub fn build_firmware(
    board: &str,
    default: bool,
    env: &[(&str, &str)],
    label: &str,
) -> Result<Sizes, String> {
    let features = [board];
    let elf = Build {
        bins: &["wmr-firmware"],
        no_default_features: !default,
        features: if default { &[] } else { &features },
        env,
    }
    .run(label)?;
    analyse(elf.first().ok_or("no ELF built")?)
}

/// The task: every board that builds is reported; the default board
/// (`board-qemu`) must build.
pub fn size() -> crate::Result {
    let mut results = Vec::new();
    for (board, default) in BOARDS {
        eprintln!("\n==> wmr-firmware, {board}");
        let result = build_firmware(board, default, &[], &format!("firmware-{board}"));
        if let Err(e) = &result {
            if default {
                return Err(format!("{board}: {e}"));
            }
            eprintln!("    {board}: not built ({e}); reported as such");
        }
        results.push((board, result));
    }
    let md = markdown(&results);
    print!("\n{md}");
    let path = write_report(REPORT, &md)?;
    eprintln!("\nwritten to {}", path.display());
    Ok(())
}

/// The report's markdown.
pub fn markdown(results: &[(&str, Result<Sizes, String>)]) -> String {
    let mut md = String::new();
    let opt_level = std::env::var("CARGO_PROFILE_RELEASE_OPT_LEVEL")
        .map(|l| format!(", `CARGO_PROFILE_RELEASE_OPT_LEVEL={l}`"))
        .unwrap_or_default();
    let _ = writeln!(
        md,
        "Size of `wmr-firmware` (release{opt_level}, thumbv7em-none-eabihf, {}), from \
         the ELF's section headers. Flash = `.vector_table + .text + .rodata + \
         .data`; static RAM = `.data + .bss + .uninit` (the stack takes the rest of \
         RAM). Regenerate with `cargo xtask size`.\n",
        rustc_version()
    );
    md.push_str("| build | flash | static RAM |");
    let names: Vec<&str> = FLASH
        .iter()
        .chain(RAM.iter().filter(|s| !FLASH.contains(s)))
        .copied()
        .collect();
    for name in &names {
        let _ = write!(md, " `{name}` |");
    }
    md.push_str("\n| --- | ---: | ---: |");
    for _ in &names {
        md.push_str(" ---: |");
    }
    md.push('\n');
    for (board, result) in results {
        match result {
            Ok(s) => {
                let _ = write!(
                    md,
                    "| `{board}` | {} | {} |",
                    bytes_kib(s.flash),
                    bytes_kib(s.ram)
                );
                for (_, size) in &s.sections {
                    let _ = write!(md, " {} |", grouped(*size));
                }
            }
            Err(_) => {
                let _ = write!(md, "| `{board}` | does not build | |");
                for _ in &names {
                    md.push_str(" |");
                }
            }
        }
        md.push('\n');
    }
    for (board, result) in results {
        let Ok(s) = result else { continue };
        for (name, size) in &s.other {
            let _ = writeln!(
                md,
                "\n`{board}` also has allocated section `{name}` ({} B), counted in neither.",
                grouped(*size)
            );
        }
        let _ = writeln!(
            md,
            "\n`{board}`: the {} biggest symbols\n\n| bytes | section | symbol |\n| ---: | --- | --- |",
            s.symbols.len()
        );
        for (size, section, name) in &s.symbols {
            let _ = writeln!(
                md,
                "| {} | `{section}` | `{}` |",
                grouped(*size),
                name.replace('|', "\\|").replace('`', "'")
            );
        }
    }
    md
}
