//! `cargo xtask size`: flash and static RAM of the release firmware, from
//! the ELF's section headers, and its biggest symbols; and the check that
//! it links no software double-precision routine (the core computes in
//! `f32` on the Cortex-M4F's single-precision FPU: an `f64` operation
//! anywhere in the firmware costs hundreds of instructions, see
//! [`soft_f64_routine`]).

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
    /// Every software double-precision routine in the symbol table (name
    /// as [`soft_f64_routine`] matched it), sorted; expected: none.
    pub soft_f64: Vec<String>,
}

/// Software double-precision routines of compiler-builtins / compiler-rt
/// that the ARM EABI prefix `__aeabi_d` does not catch.
const SOFT_F64: [&str; 31] = [
    "__adddf3",
    "__subdf3",
    "__muldf3",
    "__divdf3",
    "__negdf2",
    "__powidf2",
    "__eqdf2",
    "__nedf2",
    "__ltdf2",
    "__ledf2",
    "__gtdf2",
    "__gedf2",
    "__unorddf2",
    "__cmpdf2",
    "__extendsfdf2",
    "__extendhfdf2",
    "__truncdfsf2",
    "__truncdfhf2",
    "__fixdfsi",
    "__fixdfdi",
    "__fixdfti",
    "__fixunsdfsi",
    "__fixunsdfdi",
    "__fixunsdfti",
    "__floatsidf",
    "__floatdidf",
    "__floattidf",
    "__floatunsidf",
    "__floatundidf",
    "__floatuntidf",
    "__aeabi_f2d",
];

/// Whether a (demangled) symbol is a software double-precision routine:
/// its last path segment is one of [`SOFT_F64`] or an ARM EABI `f64`
/// helper (`__aeabi_d*`: `dadd`, `dmul`, `dcmpeq`, `d2f`, …, and the
/// integer-to-`f64` conversions `__aeabi_i2d`, `__aeabi_ui2d`,
/// `__aeabi_l2d`, `__aeabi_ul2d`). Returns that segment.
pub fn soft_f64_routine(symbol: &str) -> Option<&str> {
    let base = symbol.rsplit("::").next().unwrap_or(symbol);
    let eabi_int_to_f64 = ["__aeabi_i2d", "__aeabi_ui2d", "__aeabi_l2d", "__aeabi_ul2d"];
    (base.starts_with("__aeabi_d") || eabi_int_to_f64.contains(&base) || SOFT_F64.contains(&base))
        .then_some(base)
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

    let soft_f64: BTreeSet<String> = file
        .symbols()
        .filter_map(|s| {
            let name = format!("{:#}", rustc_demangle::demangle(s.name().ok()?));
            soft_f64_routine(&name).map(str::to_string)
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
        soft_f64: soft_f64.into_iter().collect(),
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
/// (`board-qemu`) must build, and no ELF that built may contain a software
/// double-precision routine.
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
    let (budget_table, verdict) = check_budgets(&results)?;
    print!("\n{budget_table}");
    let path = write_report(REPORT, &format!("{md}\n{budget_table}"))?;
    eprintln!("\nwritten to {}", path.display());
    soft_f64_check(&results)?;
    verdict
}

/// Each built board's flash against `firmware/budgets.toml`: its budget
/// (regressions) and its hard limit.
fn check_budgets(
    results: &[(&str, Result<Sizes, String>)],
) -> Result<(String, crate::Result), String> {
    let budgets = crate::budgets::Budgets::load()?;
    let flash = |board: &str| {
        results
            .iter()
            .find(|(b, _)| *b == board)
            .and_then(|(_, r)| r.as_ref().ok())
            .map(|s| s.flash as f64)
    };
    // A board that did not build is reported as such above; its budget
    // waits for it.
    let built: std::collections::BTreeMap<String, f64> = budgets
        .flash_bytes
        .iter()
        .filter(|(board, _)| flash(board).is_some())
        .map(|(board, &b)| (board.clone(), b))
        .collect();
    let mut verdicts = budgets.check("flash_bytes", &built, flash)?;
    for (board, &limit) in &budgets.flash_limit_bytes {
        if let Some(bytes) = flash(board) {
            // A hard limit: no tolerance, never stale.
            verdicts.push(crate::budgets::Verdict {
                what: format!("flash_limit_bytes {board}"),
                figure: bytes,
                budget: limit,
                over: bytes > limit,
                stale: false,
            });
        }
    }
    let (md, verdict) = crate::budgets::report(&verdicts, budgets.tolerance);
    Ok((
        format!("Budgets (`{}`):\n\n{md}", crate::budgets::FILE),
        verdict,
    ))
}

/// Err naming every board whose ELF links a software `f64` routine, and
/// the routines.
pub fn soft_f64_check(results: &[(&str, Result<Sizes, String>)]) -> crate::Result {
    let offenders: Vec<String> = results
        .iter()
        .filter_map(|(board, r)| {
            let s = r.as_ref().ok()?;
            (!s.soft_f64.is_empty()).then(|| format!("{board}: {}", s.soft_f64.join(", ")))
        })
        .collect();
    if offenders.is_empty() {
        return Ok(());
    }
    Err(format!(
        "the release firmware links software double-precision routines ({}). The \
         Cortex-M4F has a single-precision FPU only: find the `f64` operation that \
         pulls them in (`llvm-objdump -d` on the ELF in target/xtask/elf/, look for \
         the callers of these symbols) and make it `f32`; the core's default math \
         backend computes in `f32` only (core/src/math/).",
        offenders.join("; ")
    ))
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
        if s.soft_f64.is_empty() {
            let _ = writeln!(
                md,
                "\n`{board}` links no software double-precision routine (`__aeabi_d*`, \
                 `__adddf3`, `__muldf3`, `__extendsfdf2`, …)."
            );
        } else {
            let _ = writeln!(
                md,
                "\n**`{board}` links software double-precision routines** (the check \
                 fails): {}.",
                s.soft_f64
                    .iter()
                    .map(|n| format!("`{n}`"))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recognises_software_f64_routines() {
        for name in [
            "__aeabi_dadd",
            "__aeabi_dcmpun",
            "__aeabi_d2f",
            "__aeabi_f2d",
            "__aeabi_ui2d",
            "compiler_builtins::float::add::__adddf3",
            "compiler_builtins::float::mul::__muldf3",
            "compiler_builtins::float::extend::__extendsfdf2",
            "__truncdfsf2",
        ] {
            assert!(soft_f64_routine(name).is_some(), "{name}");
        }
        for name in [
            "__aeabi_fadd",
            "__aeabi_f2iz",
            "__addsf3",
            "__aeabi_uldivmod",
            "compiler_builtins::int::mul::__multi3",
            "libm::math::sqrtf::sqrtf",
            "wmr_core::math::kernels::sincos",
            "_defmt_write",
        ] {
            assert!(soft_f64_routine(name).is_none(), "{name}");
        }
    }

    #[test]
    fn the_check_names_the_board_and_the_routines() {
        let sizes = |soft_f64: &[&str]| Sizes {
            sections: Vec::new(),
            flash: 0,
            ram: 0,
            other: Vec::new(),
            symbols: Vec::new(),
            soft_f64: soft_f64.iter().map(|s| (*s).to_string()).collect(),
        };
        assert!(soft_f64_check(&[("board-qemu", Ok(sizes(&[])))]).is_ok());
        let e = soft_f64_check(&[
            ("board-qemu", Ok(sizes(&[]))),
            ("board-blackpill", Ok(sizes(&["__adddf3", "__aeabi_dmul"]))),
            ("board-x", Err("does not build".into())),
        ])
        .unwrap_err();
        assert!(e.contains("board-blackpill: __adddf3, __aeabi_dmul"), "{e}");
        assert!(!e.contains("board-qemu") && !e.contains("board-x"), "{e}");
    }
}
