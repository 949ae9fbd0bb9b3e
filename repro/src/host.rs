//! The host CPU a native timing ran on, and which machine config models it.

/// What `/proc/cpuinfo` says of the host's first CPU.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct HostCpu {
    /// `vendor_id` (`AuthenticAMD`, `GenuineIntel`).
    pub vendor: String,
    /// `cpu family`.
    pub family: u32,
    /// `model`.
    pub model: u32,
    /// `model name`.
    pub name: String,
    /// Whether the host runs AVX2 and FMA (the avx2 flavour's instructions).
    pub avx2: bool,
    /// Whether the host runs AVX-512F.
    pub avx512: bool,
}

impl HostCpu {
    /// This host (empty fields where `/proc/cpuinfo` cannot be read).
    #[must_use]
    pub fn detect() -> HostCpu {
        let text = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
        let mut h = HostCpu::parse(&text);
        #[cfg(target_arch = "x86_64")]
        {
            h.avx2 = std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma");
            h.avx512 = std::arch::is_x86_feature_detected!("avx512f");
        }
        h
    }

    /// The first processor's entry of a `/proc/cpuinfo` text (flags read
    /// from its `flags` line).
    #[must_use]
    pub fn parse(cpuinfo: &str) -> HostCpu {
        let mut h = HostCpu::default();
        let first = cpuinfo.split("\n\n").next().unwrap_or("");
        for line in first.lines() {
            let Some((k, v)) = line.split_once(':') else {
                continue;
            };
            let v = v.trim();
            match k.trim() {
                "vendor_id" => h.vendor = v.to_string(),
                "cpu family" => h.family = v.parse().unwrap_or(0),
                "model" => h.model = v.parse().unwrap_or(0),
                "model name" => h.name = v.to_string(),
                "flags" => {
                    let has = |f: &str| v.split_whitespace().any(|x| x == f);
                    h.avx2 = has("avx2") && has("fma");
                    h.avx512 = has("avx512f");
                }
                _ => {}
            }
        }
        h
    }

    /// One line for a report: name, vendor, family and model, vector ISA.
    #[must_use]
    pub fn describe(&self) -> String {
        let isa = match (self.avx512, self.avx2) {
            (true, _) => "AVX-512F, AVX2+FMA",
            (false, true) => "AVX2+FMA",
            _ => "no AVX2",
        };
        let name = if self.name.is_empty() {
            "unknown CPU"
        } else {
            &self.name
        };
        format!(
            "{name} ({} family {:#x} model {:#x}, {isa})",
            self.vendor, self.family, self.model
        )
    }

    /// [`HostCpu::describe`] and what this binary was built for
    /// ([`built_for`]).
    #[must_use]
    pub fn describe_build(&self) -> String {
        format!("{}, {}", self.describe(), built_for())
    }

    /// The built-in machine config that models this CPU's core, and why;
    /// `None` when no config does (with what the CPU is).
    ///
    /// AMD family 17h models 00h-2Fh (01h Naples and Summit Ridge, 08h
    /// Pinnacle Ridge, 11h Raven Ridge, 18h Picasso, 20h Dali) are Zen and
    /// Zen+; 30h and above (31h Rome, 60h Renoir, 71h Matisse) Zen 2, which
    /// has no config of its own (the nearest is named).
    /// AMD family 19h model ranges (AMD's processor programming references,
    /// as Linux's `arch/x86` tables list them): 00h-0Fh Milan, 20h-2Fh
    /// Vermeer, 40h-5Fh Rembrandt/Cezanne are Zen 3; 10h-1Fh Genoa, 60h-7Fh
    /// Raphael/Phoenix, A0h-AFh Bergamo are Zen 4. Intel family 6 (Intel's
    /// model list, as Linux's `arch/x86/include/asm/intel-family.h` names
    /// them): 6Ah and 6Ch Ice Lake-SP and -D; 55h Skylake-SP, Cascade Lake
    /// and Cooper Lake, 8Fh Sapphire Rapids and CFh Emerald Rapids have no
    /// config of their own (the nearest is named).
    #[must_use]
    pub fn model_config(&self) -> (Option<&'static str>, String) {
        let (f, m) = (self.family, self.model);
        let zen2 = self.vendor == "AuthenticAMD" && f == 0x17 && m >= 0x30;
        if self.vendor == "AuthenticAMD" && f == 0x17 && !zen2 {
            let why = format!("AMD family 17h model {m:#x}: Zen or Zen+");
            return (Some("zen1"), why);
        }
        if self.vendor == "AuthenticAMD" && f == 0x19 {
            let zen4 = matches!(m, 0x10..=0x1f | 0x60..=0x7f | 0xa0..=0xaf);
            return if zen4 {
                (Some("zen4"), format!("AMD family 19h model {m:#x}: Zen 4"))
            } else {
                (Some("zen3"), format!("AMD family 19h model {m:#x}: Zen 3"))
            };
        }
        let intel = self.vendor == "GenuineIntel" && f == 6;
        if intel && matches!(m, 0x6a | 0x6c) {
            let why = format!("Intel family 6 model {m:#x}: Ice Lake-SP (Sunny Cove)");
            return (Some("icelake-sp"), why);
        }
        let nearest = match (intel, m) {
            (true, 0x55) => " (Skylake-SP/Cascade Lake; the nearest config is icelake-sp)",
            (true, 0x8f | 0xcf) => {
                " (Sapphire/Emerald Rapids, Golden Cove cores; the nearest config is icelake-sp)"
            }
            _ if zen2 => " (Zen 2: 256-bit FP pipes as Zen 3's; the nearest config is zen3)",
            _ => "",
        };
        (
            None,
            format!(
                "no built-in config models {} family {f:#x} model {m:#x}{nearest} (configs exist for AMD Zen, Zen 3, Zen 4 and Intel Ice Lake-SP)",
                if self.vendor.is_empty() { "this CPU" } else { &self.vendor }
            ),
        )
    }
}

/// Per instruction set the native backend's code may use: its name,
/// whether this binary was compiled to use it (`.cargo/config.toml`'s
/// `target-cpu`), whether this host has it.
macro_rules! feature_table {
    ($($f:tt),*) => {
        #[cfg(target_arch = "x86_64")]
        fn feature_table() -> Vec<(&'static str, bool, bool)> {
            vec![$(($f, cfg!(target_feature = $f), std::arch::is_x86_feature_detected!($f))),*]
        }
        #[cfg(not(target_arch = "x86_64"))]
        fn feature_table() -> Vec<(&'static str, bool, bool)> {
            Vec::new()
        }
    };
}
feature_table!(
    "sse4.1", "sse4.2", "popcnt", "avx", "avx2", "fma", "bmi1", "bmi2", "lzcnt", "f16c", "avx512f",
    "avx512bw", "avx512dq", "avx512vl", "avx512cd"
);

/// The instruction sets (of those the native backend's code may use) this
/// binary was compiled to use.
#[must_use]
pub fn compiled_features() -> Vec<&'static str> {
    feature_table()
        .into_iter()
        .filter(|f| f.1)
        .map(|f| f.0)
        .collect()
}

/// The widest vector instruction set this binary's code was compiled to
/// use, for a report's input line (`built for AVX2+FMA`).
#[must_use]
pub fn built_for() -> String {
    let has = |f: &str| compiled_features().contains(&f);
    let isa = if has("avx512f") {
        "AVX-512F"
    } else if has("avx2") && has("fma") {
        "AVX2+FMA"
    } else if has("avx") {
        "AVX"
    } else if has("sse4.2") {
        "SSE4.2"
    } else {
        "baseline x86-64 (SSE2)"
    };
    format!("built for {isa}")
}

/// Instruction sets this binary was compiled to use that this host lacks
/// (a build from another machine): running its code would end in an
/// illegal instruction.
#[must_use]
pub fn missing_features() -> Vec<&'static str> {
    feature_table()
        .into_iter()
        .filter(|f| f.1 && !f.2)
        .map(|f| f.0)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const GENOA: &str = "processor\t: 0\nvendor_id\t: AuthenticAMD\ncpu family\t: 25\nmodel\t\t: 17\nmodel name\t: AMD EPYC\nflags\t\t: fpu avx2 fma avx512f\n\nprocessor\t: 1\nvendor_id\t: GenuineIntel\n";

    #[test]
    fn reads_the_first_cpu_and_names_its_model() {
        let h = HostCpu::parse(GENOA);
        assert_eq!(
            (h.vendor.as_str(), h.family, h.model),
            ("AuthenticAMD", 25, 17)
        );
        assert!(h.avx2 && h.avx512);
        assert_eq!(h.model_config().0, Some("zen4"));
        let milan = HostCpu {
            model: 1,
            ..h.clone()
        };
        assert_eq!(milan.model_config().0, Some("zen3"));
        let intel = HostCpu {
            vendor: "GenuineIntel".into(),
            family: 6,
            model: 0x55,
            ..h
        };
        assert_eq!(intel.model_config().0, None);
        assert!(intel.model_config().1.contains("GenuineIntel"));
        assert!(intel
            .model_config()
            .1
            .contains("nearest config is icelake-sp"));
        let icx = HostCpu {
            model: 0x6a,
            ..intel.clone()
        };
        assert_eq!(icx.model_config().0, Some("icelake-sp"));
        let amd_family_6 = HostCpu {
            vendor: "AuthenticAMD".into(),
            ..icx
        };
        assert_eq!(amd_family_6.model_config().0, None);
        assert_eq!(HostCpu::parse("").model_config().0, None);
        let naples = HostCpu {
            vendor: "AuthenticAMD".into(),
            family: 0x17,
            model: 0x01,
            ..HostCpu::default()
        };
        assert_eq!(naples.model_config().0, Some("zen1"));
        let rome = HostCpu {
            model: 0x31,
            ..naples
        };
        assert_eq!(rome.model_config().0, None);
        assert!(rome.model_config().1.contains("nearest config is zen3"));
    }

    #[test]
    fn this_binary_runs_on_this_host() {
        // The tests run on the machine that built them.
        assert_eq!(missing_features(), Vec::<&str>::new());
        assert_eq!(
            compiled_features().contains(&"avx2"),
            cfg!(target_feature = "avx2")
        );
    }
}
