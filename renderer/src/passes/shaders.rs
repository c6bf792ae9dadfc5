//! Every pass's shader put together as its pass does it, parsed and
//! validated with naga: a broken shader fails here, not at the first
//! frame; and the rules lavapipe's speed and memory ask of them.

use wgpu::naga;

/// Every pass's shader put together as its pass does it.
fn shaders() -> Vec<(String, String)> {
    let framed = |source: &str| format!("{}\n{source}", include_str!("frame.wgsl"));
    let fullscreen = super::overlay::fullscreen;
    let overlay = |own, source: &str| framed(&format!("{}\n{source}", fullscreen(own, 0)));
    let table = super::shadows::TABLE_VEC4S;
    let shadowed = |own, cascades, source: &str| {
        framed(&format!("{}\n{}\n{source}", fullscreen(own, table), super::shadows::lookup(cascades)))
    };
    // The lit passes without shadows and receiving them from 1 and 4 cascades.
    let lit = |source: &str, cascades| framed(&super::shadows::receiving(source, cascades));
    let terrain = format!("const COLOR_DETAIL: i32 = 2;\n{}", include_str!("terrain/terrain.wgsl"));
    let mut all = Vec::new();
    for (cascades, kind) in [(None, ""), (Some(1), " receiving 1 cascade"), (Some(4), " receiving 4 cascades")] {
        all.push(("terrain", kind, lit(&terrain, cascades)));
        all.push(("buildings", kind, lit(include_str!("buildings/buildings.wgsl"), cascades)));
        all.push(("instances", kind, lit(include_str!("instances/instances.wgsl"), cascades)));
    }
    let mut all: Vec<(String, String)> = all.into_iter().map(|(name, kind, s)| (format!("{name}{kind}"), s)).collect();
    all.extend([
        ("atmosphere".to_owned(), shadowed(8, 4, include_str!("atmosphere/atmosphere.wgsl"))),
        ("atmosphere over 1 cascade".to_owned(), shadowed(8, 1, include_str!("atmosphere/atmosphere.wgsl"))),
        (
            "atmosphere composite".to_owned(),
            format!("{}\n{}", fullscreen(0, 0), include_str!("atmosphere/composite.wgsl")),
        ),
        ("water".to_owned(), overlay(11, include_str!("water/water.wgsl"))),
        ("fog".to_owned(), overlay(7, include_str!("fog/fog.wgsl"))),
        ("shadow region clear".to_owned(), super::shadows::CLEAR.to_owned()),
    ]);
    all
}

/// Guards the frame time on lavapipe, which loads a storage buffer one
/// lane at a time: no fragment stage reads one (`params_binding`); what
/// a pixel needs comes from its vertex stage, flat.
#[test]
fn no_fragment_stage_reads_a_storage_buffer() -> Result<(), String> {
    for (name, source) in shaders() {
        let module = naga::front::wgsl::parse_str(&source)
            .map_err(|e| format!("shader '{name}': {}", e.emit_to_string(&source)))?;
        let info = naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all())
            .validate(&module)
            .map_err(|e| format!("shader '{name}': {}", e.emit_to_string(&source)))?;
        for (i, entry) in module.entry_points.iter().enumerate() {
            if entry.stage != naga::ShaderStage::Fragment {
                continue;
            }
            let uses = info.get_entry_point(i);
            for (handle, global) in module.global_variables.iter() {
                let storage = matches!(global.space, naga::AddressSpace::Storage { .. });
                if storage && uses[handle].contains(naga::valid::GlobalUse::READ) {
                    return Err(format!(
                        "shader '{name}': fragment stage '{}' reads storage buffer '{}'",
                        entry.name,
                        global.name.clone().unwrap_or_default()
                    ));
                }
            }
        }
    }
    Ok(())
}

/// Every `.wgsl` file under `dir`, a pass added later's included.
/// Every file under `dir` whose extension is `ext`.
fn files_ending(dir: &std::path::Path, ext: &str, found: &mut Vec<std::path::PathBuf>) -> std::io::Result<()> {
    for entry in std::fs::read_dir(dir)? {
        let path = entry?.path();
        if path.is_dir() {
            files_ending(&path, ext, found)?;
        } else if path.extension().is_some_and(|e| e == ext) {
            found.push(path);
        }
    }
    Ok(())
}

/// Guards the daemon's memory on lavapipe: a shader that reads a
/// uniform buffer is compiled again at every bind and never freed
/// there (`params_binding`). Every shader parses and validates, and
/// none declares a uniform buffer.
#[test]
fn no_shader_reads_a_uniform_buffer() -> Result<(), String> {
    for (name, source) in shaders() {
        let module = naga::front::wgsl::parse_str(&source)
            .map_err(|e| format!("shader '{name}': {}", e.emit_to_string(&source)))?;
        naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all())
            .validate(&module)
            .map_err(|e| format!("shader '{name}': {}", e.emit_to_string(&source)))?;
        let uniforms: Vec<String> = module
            .global_variables
            .iter()
            .filter(|(_, g)| g.space == naga::AddressSpace::Uniform)
            .map(|(_, g)| g.name.clone().unwrap_or_default())
            .collect();
        if !uniforms.is_empty() {
            return Err(format!("shader '{name}' reads uniform buffers {uniforms:?}: bind them as read-only storage"));
        }
    }
    let mut files = Vec::new();
    files_ending(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src"), "wgsl", &mut files)
        .map_err(|e| format!("cannot list the shaders: {e}"))?;
    for path in &files {
        let text = std::fs::read_to_string(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        let squeezed: String = text.chars().filter(|c| !c.is_whitespace()).collect();
        if squeezed.contains("var<uniform>") {
            return Err(format!("{} declares a uniform buffer: bind it as read-only storage", path.display()));
        }
    }
    // Nor a binding or a buffer made as one in the Rust sources (this
    // file names them only to forbid them).
    let mut sources = Vec::new();
    files_ending(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src"), "rs", &mut sources)
        .map_err(|e| format!("cannot list the sources: {e}"))?;
    let forbidden = [concat!("BufferBindingType::", "Uniform"), concat!("BufferUsages::", "UNIFORM")];
    for path in &sources {
        let text = std::fs::read_to_string(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        if let Some(what) = forbidden.iter().find(|f| text.contains(**f)) {
            return Err(format!("{} uses {what}: bind it as read-only storage", path.display()));
        }
    }
    if files.len() < 10 {
        return Err(format!("found only {} shaders under src/", files.len()));
    }
    Ok(())
}
