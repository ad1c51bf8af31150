//! PLY reading (ascii, binary little and big endian) and writing (binary
//! little endian).
//!
//! Reading understands any scalar property type (`char`/`int8`,
//! `uchar`/`uint8`, `short`, `ushort`, `int`, `uint`, `float`, `double` and
//! their sized aliases). From the `vertex` element it takes `x y z`,
//! normals `nx ny nz`, colours `red green blue` (also `r g b` and
//! `diffuse_red ...`; integer colours are divided by their type's maximum,
//! float colours taken as they are) and texture coordinates (`u v`, `s t`,
//! `texture_u texture_v` or `texture_s texture_t`). From the `face` element
//! it takes the list `vertex_indices` (or `vertex_index`); polygons with more
//! than three corners are fan-triangulated. Other elements and properties
//! are skipped.
//!
//! Writing produces `x y z` floats, optional `nx ny nz` floats, optional
//! `red green blue` uchars (colours clamped to [0, 1] and quantized to 8
//! bits), optional `u v` floats and faces as `list uchar int
//! vertex_indices`.

use crate::{MeshError, TriMesh};
use glam::{Vec2, Vec3};
use std::path::Path;
use wildlight_data::atomic::write_bytes_atomically;

/// A PLY scalar type.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    /// The divisor that maps an integer colour channel to [0, 1].
    fn color_scale(self) -> f64 {
        match self {
            Scalar::U8 => 255.0,
            Scalar::I8 => 127.0,
            Scalar::U16 => 65535.0,
            Scalar::I16 => 32767.0,
            Scalar::U32 => u32::MAX as f64,
            Scalar::I32 => i32::MAX as f64,
            Scalar::F32 | Scalar::F64 => 1.0,
        }
    }
}

/// Whether a property holds one value or a list.
#[derive(Clone, Copy, Debug)]
enum PropertyKind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Clone, Debug)]
struct Property {
    name: String,
    kind: PropertyKind,
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: usize,
    properties: Vec<Property>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Encoding {
    Ascii,
    BinaryLittleEndian,
    BinaryBigEndian,
}

#[derive(Debug)]
struct Header {
    encoding: Encoding,
    elements: Vec<Element>,
    /// Byte offset where the body starts.
    body_offset: usize,
    /// Number of header lines (the body's first line is `lines + 1`).
    lines: usize,
}

/// Reads a PLY file.
pub fn read_ply(path: &Path) -> Result<TriMesh, MeshError> {
    let bytes = std::fs::read(path).map_err(|e| MeshError::io(path, e))?;
    parse_ply(&bytes, path)
}

/// Parses PLY bytes; `path` only names the source in error messages.
pub fn parse_ply(bytes: &[u8], path: &Path) -> Result<TriMesh, MeshError> {
    let header = parse_header(bytes, path)?;
    let body = &bytes[header.body_offset..];
    let mut source: Box<dyn RowSource + '_> = match header.encoding {
        Encoding::Ascii => {
            let text = std::str::from_utf8(body)
                .map_err(|_| MeshError::invalid(path, "ascii PLY body contains non-text bytes"))?;
            Box::new(AsciiSource::new(text, header.lines + 1, path))
        }
        Encoding::BinaryLittleEndian => Box::new(BinarySource::new(body, false, path)),
        Encoding::BinaryBigEndian => Box::new(BinarySource::new(body, true, path)),
    };

    let mut mesh = TriMesh::default();
    let mut saw_vertex = false;
    for element in &header.elements {
        match element.name.as_str() {
            "vertex" => {
                read_vertices(element, source.as_mut(), &mut mesh, path)?;
                saw_vertex = true;
            }
            "face" => read_faces(element, source.as_mut(), &mut mesh, path)?,
            _ => skip_rows(element, source.as_mut())?,
        }
    }
    if !saw_vertex {
        return Err(MeshError::invalid(
            path,
            "no `vertex` element in the header",
        ));
    }
    mesh.validate(path)?;
    Ok(mesh)
}

fn parse_header(bytes: &[u8], path: &Path) -> Result<Header, MeshError> {
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut offset = 0;
    let mut line_no = 0;
    loop {
        let Some(len) = bytes[offset..].iter().position(|&b| b == b'\n') else {
            return Err(MeshError::invalid(
                path,
                "PLY header has no `end_header` line",
            ));
        };
        line_no += 1;
        let raw = &bytes[offset..offset + len];
        offset += len + 1;
        let line = std::str::from_utf8(raw)
            .map_err(|_| MeshError::line(path, line_no, "PLY header line is not text"))?
            .trim_end_matches('\r');
        let words: Vec<&str> = line.split_whitespace().collect();
        let err = |m: String| MeshError::line(path, line_no, m);
        if line_no == 1 {
            if line.trim() != "ply" {
                return Err(err("not a PLY file (first line must be `ply`)".into()));
            }
            continue;
        }
        match words.first().copied() {
            None | Some("comment") | Some("obj_info") => {}
            Some("format") => {
                encoding = Some(match words.get(1).copied() {
                    Some("ascii") => Encoding::Ascii,
                    Some("binary_little_endian") => Encoding::BinaryLittleEndian,
                    Some("binary_big_endian") => Encoding::BinaryBigEndian,
                    other => return Err(err(format!("unknown PLY format {other:?}"))),
                });
            }
            Some("element") => {
                let (Some(name), Some(count)) = (words.get(1), words.get(2)) else {
                    return Err(err("`element` needs a name and a count".into()));
                };
                let count = count
                    .parse::<usize>()
                    .map_err(|_| err(format!("bad element count `{count}`")))?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    properties: Vec::new(),
                });
            }
            Some("property") => {
                let Some(element) = elements.last_mut() else {
                    return Err(err("`property` before any `element`".into()));
                };
                let scalar = |name: &str| {
                    Scalar::parse(name)
                        .ok_or_else(|| err(format!("unknown property type `{name}`")))
                };
                let property = match words.as_slice() {
                    ["property", "list", count, item, name] => Property {
                        name: name.to_string(),
                        kind: PropertyKind::List {
                            count: scalar(count)?,
                            item: scalar(item)?,
                        },
                    },
                    ["property", ty, name] => Property {
                        name: name.to_string(),
                        kind: PropertyKind::Scalar(scalar(ty)?),
                    },
                    _ => return Err(err(format!("malformed property line `{line}`"))),
                };
                element.properties.push(property);
            }
            Some("end_header") => break,
            Some(other) => return Err(err(format!("unexpected header keyword `{other}`"))),
        }
    }
    let encoding =
        encoding.ok_or_else(|| MeshError::invalid(path, "PLY header has no `format` line"))?;
    Ok(Header {
        encoding,
        elements,
        body_offset: offset,
        lines: line_no,
    })
}

/// A source of element rows: every property as a number or a list of numbers.
trait RowSource {
    /// Reads one row of `element`: scalar properties into `scalars[i]`,
    /// list properties into `lists[i]` (cleared first).
    fn read_row(
        &mut self,
        element: &Element,
        row: usize,
        scalars: &mut [f64],
        lists: &mut [Vec<f64>],
    ) -> Result<(), MeshError>;

    /// An error about the row just read, placed by line (ascii) or by
    /// element and row number (binary).
    fn error_at(&self, element: &Element, row: usize, message: String) -> MeshError;
}

/// Whitespace-separated tokens of an ascii body, with line numbers.
struct AsciiSource<'a> {
    lines: std::str::Lines<'a>,
    tokens: std::str::SplitWhitespace<'a>,
    /// Line number of the line `tokens` comes from.
    line: usize,
    path: &'a Path,
}

impl<'a> AsciiSource<'a> {
    fn new(text: &'a str, first_line: usize, path: &'a Path) -> Self {
        AsciiSource {
            lines: text.lines(),
            tokens: "".split_whitespace(),
            line: first_line - 1,
            path,
        }
    }

    fn next_number(&mut self, ty: Scalar) -> Result<f64, MeshError> {
        loop {
            if let Some(token) = self.tokens.next() {
                let value = token.parse::<f64>().map_err(|_| {
                    MeshError::line(self.path, self.line, format!("`{token}` is not a number"))
                })?;
                if !matches!(ty, Scalar::F32 | Scalar::F64) && value.fract() != 0.0 {
                    return Err(MeshError::line(
                        self.path,
                        self.line,
                        format!("`{token}` is not an integer"),
                    ));
                }
                return Ok(value);
            }
            let Some(next) = self.lines.next() else {
                return Err(MeshError::line(
                    self.path,
                    self.line,
                    "file ends before all elements were read",
                ));
            };
            self.line += 1;
            self.tokens = next.split_whitespace();
        }
    }
}

impl RowSource for AsciiSource<'_> {
    fn read_row(
        &mut self,
        element: &Element,
        _row: usize,
        scalars: &mut [f64],
        lists: &mut [Vec<f64>],
    ) -> Result<(), MeshError> {
        for (i, property) in element.properties.iter().enumerate() {
            match property.kind {
                PropertyKind::Scalar(ty) => scalars[i] = self.next_number(ty)?,
                PropertyKind::List { count, item } => {
                    let n = self.next_number(count)?;
                    if n < 0.0 {
                        return Err(MeshError::line(
                            self.path,
                            self.line,
                            "negative list length",
                        ));
                    }
                    lists[i].clear();
                    for _ in 0..n as usize {
                        let v = self.next_number(item)?;
                        lists[i].push(v);
                    }
                }
            }
        }
        Ok(())
    }

    fn error_at(&self, _element: &Element, _row: usize, message: String) -> MeshError {
        MeshError::line(self.path, self.line, message)
    }
}

/// A binary body with either byte order.
struct BinarySource<'a> {
    bytes: &'a [u8],
    offset: usize,
    big_endian: bool,
    path: &'a Path,
}

impl<'a> BinarySource<'a> {
    fn new(bytes: &'a [u8], big_endian: bool, path: &'a Path) -> Self {
        BinarySource {
            bytes,
            offset: 0,
            big_endian,
            path,
        }
    }

    fn take<const N: usize>(&mut self) -> Option<[u8; N]> {
        let slice = self.bytes.get(self.offset..self.offset + N)?;
        self.offset += N;
        let mut out = [0u8; N];
        out.copy_from_slice(slice);
        if self.big_endian {
            out.reverse();
        }
        Some(out)
    }

    fn number(&mut self, ty: Scalar) -> Option<f64> {
        Some(match ty {
            Scalar::I8 => i8::from_le_bytes(self.take()?) as f64,
            Scalar::U8 => u8::from_le_bytes(self.take()?) as f64,
            Scalar::I16 => i16::from_le_bytes(self.take()?) as f64,
            Scalar::U16 => u16::from_le_bytes(self.take()?) as f64,
            Scalar::I32 => i32::from_le_bytes(self.take()?) as f64,
            Scalar::U32 => u32::from_le_bytes(self.take()?) as f64,
            Scalar::F32 => f32::from_le_bytes(self.take()?) as f64,
            Scalar::F64 => f64::from_le_bytes(self.take()?),
        })
    }
}

impl RowSource for BinarySource<'_> {
    fn read_row(
        &mut self,
        element: &Element,
        row: usize,
        scalars: &mut [f64],
        lists: &mut [Vec<f64>],
    ) -> Result<(), MeshError> {
        let truncated = || {
            MeshError::invalid(
                self.path,
                format!(
                    "file ends inside {} {row} of {} (truncated binary body)",
                    element.name, element.count
                ),
            )
        };
        for (i, property) in element.properties.iter().enumerate() {
            match property.kind {
                PropertyKind::Scalar(ty) => {
                    scalars[i] = self.number(ty).ok_or_else(truncated)?;
                }
                PropertyKind::List { count, item } => {
                    let n = self.number(count).ok_or_else(truncated)?;
                    if n < 0.0 {
                        return Err(MeshError::invalid(
                            self.path,
                            format!("{} {row}: negative list length", element.name),
                        ));
                    }
                    let n = n as usize;
                    if self.bytes.len() - self.offset < n * item.size() {
                        return Err(truncated());
                    }
                    lists[i].clear();
                    for _ in 0..n {
                        let v = self.number(item).ok_or_else(truncated)?;
                        lists[i].push(v);
                    }
                }
            }
        }
        Ok(())
    }

    fn error_at(&self, element: &Element, row: usize, message: String) -> MeshError {
        MeshError::invalid(self.path, format!("{} {row}: {message}", element.name))
    }
}

fn find(element: &Element, names: &[&str]) -> Option<(usize, Scalar)> {
    element
        .properties
        .iter()
        .enumerate()
        .find_map(|(i, p)| match p.kind {
            PropertyKind::Scalar(ty) if names.contains(&p.name.as_str()) => Some((i, ty)),
            _ => None,
        })
}

/// Finds three scalar properties, each under one of several names.
fn find3(element: &Element, names: [&[&str]; 3]) -> Option<[(usize, Scalar); 3]> {
    Some([
        find(element, names[0])?,
        find(element, names[1])?,
        find(element, names[2])?,
    ])
}

fn read_vertices(
    element: &Element,
    source: &mut dyn RowSource,
    mesh: &mut TriMesh,
    path: &Path,
) -> Result<(), MeshError> {
    let position = find3(element, [&["x"], &["y"], &["z"]])
        .ok_or_else(|| MeshError::invalid(path, "vertex element lacks x, y or z"))?;
    let normal = find3(element, [&["nx"], &["ny"], &["nz"]]);
    let color = find3(
        element,
        [
            &["red", "r", "diffuse_red"],
            &["green", "g", "diffuse_green"],
            &["blue", "b", "diffuse_blue"],
        ],
    );
    let uv = find(element, &["u", "s", "texture_u", "texture_s"])
        .zip(find(element, &["v", "t", "texture_v", "texture_t"]));

    let n = element.count;
    let mut scalars = vec![0.0; element.properties.len()];
    let mut lists = vec![Vec::new(); element.properties.len()];
    mesh.positions.reserve(n);
    let mut normals = normal.map(|_| Vec::with_capacity(n));
    let mut colors = color.map(|_| Vec::with_capacity(n));
    let mut uvs = uv.map(|_| Vec::with_capacity(n));
    for row in 0..n {
        source.read_row(element, row, &mut scalars, &mut lists)?;
        let p = Vec3::new(
            scalars[position[0].0] as f32,
            scalars[position[1].0] as f32,
            scalars[position[2].0] as f32,
        );
        if !p.is_finite() {
            return Err(source.error_at(element, row, "vertex position is not finite".into()));
        }
        mesh.positions.push(p);
        if let (Some(out), Some(idx)) = (&mut normals, normal) {
            out.push(Vec3::new(
                scalars[idx[0].0] as f32,
                scalars[idx[1].0] as f32,
                scalars[idx[2].0] as f32,
            ));
        }
        if let (Some(out), Some(idx)) = (&mut colors, color) {
            out.push(Vec3::new(
                (scalars[idx[0].0] / idx[0].1.color_scale()) as f32,
                (scalars[idx[1].0] / idx[1].1.color_scale()) as f32,
                (scalars[idx[2].0] / idx[2].1.color_scale()) as f32,
            ));
        }
        if let (Some(out), Some((u, v))) = (&mut uvs, uv) {
            out.push(Vec2::new(scalars[u.0] as f32, scalars[v.0] as f32));
        }
    }
    mesh.normals = normals;
    mesh.colors = colors;
    mesh.uvs = uvs;
    Ok(())
}

fn read_faces(
    element: &Element,
    source: &mut dyn RowSource,
    mesh: &mut TriMesh,
    path: &Path,
) -> Result<(), MeshError> {
    let lists_at: Vec<usize> = element
        .properties
        .iter()
        .enumerate()
        .filter(|(_, p)| matches!(p.kind, PropertyKind::List { .. }))
        .map(|(i, _)| i)
        .collect();
    let index_property = element
        .properties
        .iter()
        .position(|p| {
            matches!(p.kind, PropertyKind::List { .. })
                && (p.name == "vertex_indices" || p.name == "vertex_index")
        })
        .or_else(|| lists_at.first().copied())
        .ok_or_else(|| MeshError::invalid(path, "face element has no vertex index list"))?;
    let mut scalars = vec![0.0; element.properties.len()];
    let mut lists = vec![Vec::new(); element.properties.len()];
    mesh.triangles.reserve(element.count);
    for row in 0..element.count {
        source.read_row(element, row, &mut scalars, &mut lists)?;
        let corners = &lists[index_property];
        if corners.len() < 3 {
            return Err(source.error_at(
                element,
                row,
                format!("face has {} corners (at least 3 needed)", corners.len()),
            ));
        }
        if let Some(bad) = corners.iter().find(|&&v| v < 0.0 || v > u32::MAX as f64) {
            return Err(source.error_at(element, row, format!("invalid vertex index {bad}")));
        }
        // Fan triangulation of a polygon (v0, v1, ..., vk).
        let v0 = corners[0] as u32;
        for k in 1..corners.len() - 1 {
            mesh.triangles
                .push([v0, corners[k] as u32, corners[k + 1] as u32]);
        }
    }
    Ok(())
}

fn skip_rows(element: &Element, source: &mut dyn RowSource) -> Result<(), MeshError> {
    let mut scalars = vec![0.0; element.properties.len()];
    let mut lists = vec![Vec::new(); element.properties.len()];
    for row in 0..element.count {
        source.read_row(element, row, &mut scalars, &mut lists)?;
    }
    Ok(())
}

/// Writes `mesh` as binary little-endian PLY, atomically.
pub fn write_ply(mesh: &TriMesh, path: &Path) -> Result<(), MeshError> {
    mesh.validate(path)?;
    let bytes = encode_ply(mesh);
    write_bytes_atomically(path, &bytes)?;
    Ok(())
}

/// Encodes `mesh` as binary little-endian PLY bytes.
pub fn encode_ply(mesh: &TriMesh) -> Vec<u8> {
    let mut header = String::from("ply\nformat binary_little_endian 1.0\ncomment wildlight-mesh\n");
    header += &format!("element vertex {}\n", mesh.positions.len());
    header += "property float x\nproperty float y\nproperty float z\n";
    if mesh.normals.is_some() {
        header += "property float nx\nproperty float ny\nproperty float nz\n";
    }
    if mesh.colors.is_some() {
        header += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    }
    if mesh.uvs.is_some() {
        header += "property float u\nproperty float v\n";
    }
    header += &format!("element face {}\n", mesh.triangles.len());
    header += "property list uchar int vertex_indices\nend_header\n";

    let mut out = header.into_bytes();
    out.reserve(mesh.positions.len() * 32 + mesh.triangles.len() * 13);
    for (i, p) in mesh.positions.iter().enumerate() {
        for c in p.to_array() {
            out.extend_from_slice(&c.to_le_bytes());
        }
        if let Some(normals) = &mesh.normals {
            for c in normals[i].to_array() {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
        if let Some(colors) = &mesh.colors {
            for c in colors[i].to_array() {
                out.push((c.clamp(0.0, 1.0) * 255.0).round() as u8);
            }
        }
        if let Some(uvs) = &mesh.uvs {
            for c in uvs[i].to_array() {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    for tri in &mesh.triangles {
        out.push(3);
        for v in tri {
            out.extend_from_slice(&(*v as i32).to_le_bytes());
        }
    }
    out
}
