//! Exports read back with small independent readers (NumPy files parsed by hand) and the
//! PNG decoded, with the complex's own counts to compare against.

use std::io::Read;
use std::path::{Path, PathBuf};

use isomesh::complex::Complex;
use isomesh::export::picture::Picture;
use isomesh::export::{write_mesh, write_mesh_as, Encoding, Mesh, MeshFormat, Projection};
use isomesh::expr::{preset, Problem};
use isomesh::trace::{trace, CpuOracle, TraceOptions};

fn problem(name: &str, params: &[(&str, f64)]) -> Problem {
    let params: Vec<(String, f64)> = params.iter().map(|(n, v)| (n.to_string(), *v)).collect();
    preset(name, &params).unwrap()
}

fn build(p: &Problem) -> Complex {
    let tri = p.triangulation.build(p.dim()).unwrap();
    let opts = TraceOptions {
        seeds: p.seeds.clone(),
        bbox: p.bbox.clone(),
        ..TraceOptions::default()
    };
    let s = trace(&p.system, &tri, &CpuOracle::new(&p.system), &opts).unwrap();
    Complex::build(&s, &p.system, p.bbox.as_deref()).unwrap()
}

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("isomesh-export-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn text(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap()
}

fn floats(s: &str) -> Vec<f64> {
    s.split_whitespace().map(|t| t.parse().unwrap()).collect()
}

/// (vertices, cells as vertex lists) of an ASCII PLY file.
fn read_ply(s: &str) -> (usize, Vec<Vec<usize>>, String) {
    let (head, body) = s.split_once("end_header\n").unwrap();
    let count = |el: &str| -> usize {
        head.lines()
            .find_map(|l| l.strip_prefix(&format!("element {el} ")))
            .map_or(0, |n| n.parse().unwrap())
    };
    let (nv, nf, ne) = (count("vertex"), count("face"), count("edge"));
    let lines: Vec<&str> = body.lines().collect();
    assert_eq!(lines.len(), nv + nf + ne);
    for l in &lines[..nv] {
        assert_eq!(floats(l).len(), 3);
    }
    let cells = lines[nv..]
        .iter()
        .map(|l| {
            let v: Vec<usize> = l.split_whitespace().map(|t| t.parse().unwrap()).collect();
            if nf > 0 {
                assert_eq!(v[0], v.len() - 1);
                v[1..].to_vec()
            } else {
                v
            }
        })
        .collect();
    (nv, cells, head.to_string())
}

fn read_obj(s: &str) -> (usize, Vec<Vec<usize>>) {
    let mut nv = 0;
    let mut cells = Vec::new();
    for l in s.lines() {
        let mut t = l.split_whitespace();
        match t.next() {
            Some("v") => {
                let xyz: Vec<f64> = t.map(|x| x.parse().unwrap()).collect();
                assert_eq!(xyz.len(), 3);
                nv += 1;
            }
            Some("f") | Some("l") => {
                cells.push(t.map(|x| x.parse::<usize>().unwrap() - 1).collect());
            }
            _ => {}
        }
    }
    (nv, cells)
}

fn read_off(s: &str) -> (usize, Vec<Vec<usize>>) {
    let mut lines = s.lines().filter(|l| !l.starts_with('#'));
    assert_eq!(lines.next(), Some("OFF"));
    let counts: Vec<usize> = lines
        .next()
        .unwrap()
        .split_whitespace()
        .map(|t| t.parse().unwrap())
        .collect();
    let (nv, nf) = (counts[0], counts[1]);
    let rest: Vec<&str> = lines.collect();
    assert_eq!(rest.len(), nv + nf);
    let cells = rest[nv..]
        .iter()
        .map(|l| {
            let v: Vec<usize> = l.split_whitespace().map(|t| t.parse().unwrap()).collect();
            assert_eq!(v[0], v.len() - 1);
            v[1..].to_vec()
        })
        .collect();
    (nv, cells)
}

/// Section sizes of a Medit file, by keyword, with the rows checked for width.
fn read_medit(s: &str) -> std::collections::HashMap<String, usize> {
    let lines: Vec<&str> = s.lines().filter(|l| !l.starts_with('#')).collect();
    let mut out = std::collections::HashMap::new();
    let mut i = 0;
    while i < lines.len() {
        let key = lines[i].trim();
        let width = match key {
            "Vertices" => 4,
            "Edges" => 3,
            "Triangles" => 4,
            "Tetrahedra" => 5,
            _ => {
                i += 1;
                continue;
            }
        };
        let n: usize = lines[i + 1].trim().parse().unwrap();
        for row in &lines[i + 2..i + 2 + n] {
            assert_eq!(row.split_whitespace().count(), width, "{key}: {row}");
        }
        out.insert(key.to_string(), n);
        i += 2 + n;
    }
    out
}

/// The text of a VTU DataArray named `name`.
fn vtu_array<'a>(s: &'a str, name: &str) -> &'a str {
    let at = s.find(&format!("Name=\"{name}\"")).unwrap();
    let start = at + s[at..].find('>').unwrap() + 1;
    let end = start + s[start..].find("</DataArray>").unwrap();
    &s[start..end]
}

fn attr(s: &str, name: &str) -> usize {
    let at = s.find(&format!("{name}=\"")).unwrap() + name.len() + 2;
    s[at..at + s[at..].find('"').unwrap()].parse().unwrap()
}

fn npz_entries(path: &Path) -> std::collections::HashMap<String, Vec<u8>> {
    let mut z = zip::ZipArchive::new(std::fs::File::open(path).unwrap()).unwrap();
    (0..z.len())
        .map(|i| {
            let mut f = z.by_index(i).unwrap();
            let mut bytes = Vec::new();
            f.read_to_end(&mut bytes).unwrap();
            (f.name().trim_end_matches(".npy").to_string(), bytes)
        })
        .collect()
}

/// Parses a `.npy` file by hand (version 1 header, little-endian, C order): its shape and
/// its data, after checking the dtype.
fn read_npy<T: FromLe>(bytes: &[u8], dtype: &str) -> (Vec<usize>, Vec<T>) {
    assert_eq!(&bytes[..6], b"\x93NUMPY");
    let len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let header = std::str::from_utf8(&bytes[10..10 + len]).unwrap();
    assert!(header.contains(&format!("'descr': '{dtype}'")), "{header}");
    assert!(header.contains("'fortran_order': False"), "{header}");
    let at = header.find("'shape': (").unwrap() + 10;
    let shape: Vec<usize> = header[at..at + header[at..].find(')').unwrap()]
        .split(',')
        .filter(|t| !t.trim().is_empty())
        .map(|t| t.trim().parse().unwrap())
        .collect();
    let data: Vec<T> = bytes[10 + len..]
        .chunks_exact(std::mem::size_of::<T>())
        .map(T::from_le)
        .collect();
    assert_eq!(data.len(), shape.iter().product::<usize>());
    (shape, data)
}

trait FromLe {
    fn from_le(b: &[u8]) -> Self;
}
impl FromLe for f64 {
    fn from_le(b: &[u8]) -> Self {
        f64::from_le_bytes(b.try_into().unwrap())
    }
}
impl FromLe for u32 {
    fn from_le(b: &[u8]) -> Self {
        u32::from_le_bytes(b.try_into().unwrap())
    }
}
impl FromLe for u64 {
    fn from_le(b: &[u8]) -> Self {
        u64::from_le_bytes(b.try_into().unwrap())
    }
}

#[test]
fn surface_exports_read_back_with_the_same_counts() {
    let p = problem("torus", &[("edge", 0.1)]);
    let c = build(&p);
    let mesh = Mesh::new(&c, Some(&p.system), &Projection::Auto, "torus");
    let (nv, nf) = (c.vertex_count(), c.level(2).len());
    let tris: usize = mesh.triangles.len();
    let out = dir("surface");
    for (name, format) in MeshFormat::ALL {
        let path = out.join(format!("torus.{name}"));
        write_mesh_as(&path, &mesh, format, Encoding::Ascii).unwrap();
        assert!(out.read_dir().unwrap().all(|e| !e
            .unwrap()
            .file_name()
            .to_string_lossy()
            .ends_with(".partial")));
        match format {
            MeshFormat::Ply => {
                let (v, cells, _) = read_ply(&text(&path));
                assert_eq!((v, cells.len()), (nv, nf));
                assert!(cells.iter().flatten().all(|&i| i < nv));
                assert!(cells.iter().all(|c| c.len() >= 3));
            }
            MeshFormat::Obj => {
                let (v, cells) = read_obj(&text(&path));
                assert_eq!((v, cells.len()), (nv, nf));
                assert!(cells.iter().flatten().all(|&i| i < nv));
            }
            MeshFormat::Off => {
                let (v, cells) = read_off(&text(&path));
                assert_eq!((v, cells.len()), (nv, nf));
            }
            MeshFormat::Stl => {
                let bytes = std::fs::read(&path).unwrap();
                let n = u32::from_le_bytes(bytes[80..84].try_into().unwrap()) as usize;
                assert_eq!(n, tris);
                assert_eq!(bytes.len(), 84 + 50 * n);
                // Each stored normal is a unit vector.
                let f = |o: usize| f32::from_le_bytes(bytes[o..o + 4].try_into().unwrap());
                let nrm = [f(84), f(88), f(92)];
                let len = nrm.iter().map(|x| x * x).sum::<f32>().sqrt();
                assert!((len - 1.0).abs() < 1e-4);
            }
            MeshFormat::Medit => {
                let sections = read_medit(&text(&path));
                assert_eq!(sections["Vertices"], nv);
                assert_eq!(sections["Triangles"], tris);
            }
            MeshFormat::Vtu => {
                let s = text(&path);
                assert_eq!(attr(&s, "NumberOfPoints"), nv);
                assert_eq!(attr(&s, "NumberOfCells"), nf);
                assert_eq!(floats(vtu_array(&s, "coordinates")).len(), 3 * nv);
                let offsets = floats(vtu_array(&s, "offsets"));
                let conn = floats(vtu_array(&s, "connectivity"));
                assert_eq!(offsets.len(), nf);
                assert_eq!(*offsets.last().unwrap() as usize, conn.len());
                assert!(floats(vtu_array(&s, "types")).iter().all(|&t| t == 7.0));
            }
            MeshFormat::Npz => {
                // Every member deflated, and the index arrays smaller for it.
                let mut z = zip::ZipArchive::new(std::fs::File::open(&path).unwrap()).unwrap();
                for i in 0..z.len() {
                    let f = z.by_index(i).unwrap();
                    assert_eq!(f.compression(), zip::CompressionMethod::Deflated);
                    if f.name().starts_with("cells") {
                        assert!(f.compressed_size() < f.size(), "{}", f.name());
                    }
                }
                let e = npz_entries(&path);
                let (shape, v) = read_npy::<f64>(&e["vertices"], "<f8");
                assert_eq!(shape, vec![nv, 3]);
                assert_eq!(v, c.points());
                let (shape, _) = read_npy::<u32>(&e["triangles"], "<u4");
                assert_eq!(shape, vec![tris, 3]);
                for j in 1..=2 {
                    let (_, off) = read_npy::<u64>(&e[&format!("cells{j}_offsets")], "<u8");
                    assert_eq!(off.len(), c.counts()[j] + 1);
                    let (_, fac) = read_npy::<u32>(&e[&format!("cells{j}_facets")], "<u4");
                    assert_eq!(*off.last().unwrap() as usize, fac.len());
                }
            }
        }
    }
    std::fs::remove_dir_all(out).unwrap();
}

#[test]
fn curves_volumes_and_projections() {
    let out = dir("other");
    // A curve: lines in OBJ, edges in PLY, Medit and VTU.
    let p = problem("circle", &[]);
    let c = build(&p);
    let mesh = Mesh::new(&c, Some(&p.system), &Projection::Auto, "circle");
    let path = out.join("c.obj");
    write_mesh(&path, &mesh, MeshFormat::Obj).unwrap();
    let (v, lines) = read_obj(&text(&path));
    assert_eq!((v, lines.len()), (c.vertex_count(), c.level(1).len()));
    write_mesh_as(&out.join("c.ply"), &mesh, MeshFormat::Ply, Encoding::Ascii).unwrap();
    let (_, edges, _) = read_ply(&text(&out.join("c.ply")));
    assert_eq!(edges.len(), c.level(1).len());
    assert!(write_mesh(&out.join("c.off"), &mesh, MeshFormat::Off).is_err());

    // A 3-manifold: S^3 in R^4 seen on x1, x2, x3 covers the unit ball twice, so the
    // tetrahedra add up to twice its volume (less the O(edge^2) shrinkage of M-hat).
    let p = problem("sphere", &[("m", 3.0), ("d", 4.0), ("edge", 0.2)]);
    let c = build(&p);
    let mesh = Mesh::new(&c, None, &Projection::Axes(vec![0, 1, 2]), "s3");
    let path = out.join("s3.mesh");
    write_mesh(&path, &mesh, MeshFormat::Medit).unwrap();
    let sections = read_medit(&text(&path));
    assert_eq!(sections["Vertices"], c.vertex_count());
    assert_eq!(sections["Tetrahedra"], mesh.tetrahedra.len());
    let vol: f64 = mesh
        .tetrahedra
        .iter()
        .map(|t| {
            let [a, b, cc, d] = t.map(|i| &mesh.xyz[3 * i as usize..3 * i as usize + 3]);
            let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
            let v = [cc[0] - a[0], cc[1] - a[1], cc[2] - a[2]];
            let w = [d[0] - a[0], d[1] - a[1], d[2] - a[2]];
            (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
                + u[2] * (v[0] * w[1] - v[1] * w[0]))
                .abs()
                / 6.0
        })
        .sum();
    let ball = 4.0 / 3.0 * std::f64::consts::PI;
    assert!(
        (vol - 2.0 * ball).abs() < 0.05 * ball,
        "tetrahedra volume {vol}"
    );
    write_mesh_as(&out.join("s3.vtu"), &mesh, MeshFormat::Vtu, Encoding::Ascii).unwrap();
    let s = text(&out.join("s3.vtu"));
    assert_eq!(attr(&s, "NumberOfCells"), mesh.tetrahedra.len());
    assert!(write_mesh(&out.join("s3.ply"), &mesh, MeshFormat::Ply).is_err());

    // Surfaces in R^4 are projected by PCA, and the file says how.
    let p = problem("flat-torus", &[("edge", 0.3)]);
    let c = build(&p);
    let mesh = Mesh::new(&c, None, &Projection::Pca, "flat torus");
    write_mesh_as(&out.join("ft.ply"), &mesh, MeshFormat::Ply, Encoding::Ascii).unwrap();
    let (nv, faces, head) = read_ply(&text(&out.join("ft.ply")));
    assert_eq!((nv, faces.len()), (c.vertex_count(), c.level(2).len()));
    assert!(head.contains("projection: pca: centre ["), "{head}");
    write_mesh_as(&out.join("ft.vtu"), &mesh, MeshFormat::Vtu, Encoding::Ascii).unwrap();
    let s = text(&out.join("ft.vtu"));
    let coords = floats(vtu_array(&s, "coordinates"));
    assert_eq!(coords, c.points(), "the d-D coordinates are kept exactly");
    std::fs::remove_dir_all(out).unwrap();
}

#[test]
fn the_picture_decodes_at_its_size_and_is_not_blank() {
    let out = dir("png");
    for (name, params) in [
        ("torus", vec![("edge", 0.1)]),
        ("circle", vec![]),
        ("complex-cosine", vec![("edge", 0.2)]),
    ] {
        let p = problem(name, &params);
        let c = build(&p);
        let mesh = Mesh::new(&c, Some(&p.system), &Projection::Auto, name);
        let pic = Picture::render(&mesh, 320, 200, name).unwrap();
        let path = out.join(format!("{name}.png"));
        pic.write_png(&path).unwrap();
        let decoder =
            png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&path).unwrap()));
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height), (320, 200), "{name}");
        let px = &buf[..info.buffer_size()];
        let mean = px.iter().map(|&b| b as f64).sum::<f64>() / px.len() as f64;
        let var = px.iter().map(|&b| (b as f64 - mean).powi(2)).sum::<f64>() / px.len() as f64;
        assert!(var > 200.0, "{name}: pixel variance {var}");
    }
    let p = problem("circle", &[]);
    let c = build(&p);
    let mesh = Mesh::new(&c, None, &Projection::Auto, "circle");
    assert!(Picture::render(&mesh, 10, 10, "").is_err());
    std::fs::remove_dir_all(out).unwrap();
}

/// A binary little-endian PLY file: its header, the vertices (3 doubles each) and the cells
/// (uchar-counted int lists for faces, int pairs for edges).
fn read_ply_binary(bytes: &[u8]) -> (String, Vec<[f64; 3]>, Vec<Vec<usize>>) {
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let head = std::str::from_utf8(&bytes[..end]).unwrap().to_string();
    assert!(head.contains("format binary_little_endian 1.0\n"), "{head}");
    let count = |el: &str| -> usize {
        head.lines()
            .find_map(|l| l.strip_prefix(&format!("element {el} ")))
            .map_or(0, |n| n.parse().unwrap())
    };
    let (nv, nf, ne) = (count("vertex"), count("face"), count("edge"));
    let mut at = end;
    let mut take = |n: usize| {
        let b = &bytes[at..at + n];
        at += n;
        b
    };
    let verts: Vec<[f64; 3]> = (0..nv)
        .map(|_| [0; 3].map(|_| f64::from_le_bytes(take(8).try_into().unwrap())))
        .collect();
    let int = |b: &[u8]| i32::from_le_bytes(b.try_into().unwrap()) as usize;
    let mut cells = Vec::new();
    for _ in 0..nf {
        let n = take(1)[0] as usize;
        cells.push((0..n).map(|_| int(take(4))).collect());
    }
    for _ in 0..ne {
        cells.push(vec![int(take(4)), int(take(4))]);
    }
    assert_eq!(at, bytes.len(), "bytes after the last element");
    (head, verts, cells)
}

/// The arrays of a VTU file with raw appended data, by name (`Points` for the unnamed
/// points array), as their bytes, after checking each array's UInt64 size header.
fn read_vtu_binary(bytes: &[u8]) -> std::collections::HashMap<String, (String, Vec<u8>)> {
    let mark = b"<AppendedData encoding=\"raw\">\n_";
    let start = bytes.windows(mark.len()).position(|w| w == mark).unwrap();
    let xml = std::str::from_utf8(&bytes[..start]).unwrap();
    let data = &bytes[start + mark.len()..];
    assert!(xml.contains("header_type=\"UInt64\"") && xml.contains("LittleEndian"));
    let mut out = std::collections::HashMap::new();
    let mut sum = 0;
    for tag in xml.split("<DataArray ").skip(1) {
        let tag = &tag[..tag.find("/>").unwrap()];
        let get = |k: &str| {
            tag.find(&format!("{k}=\"")).map(|i| {
                let v = &tag[i + k.len() + 2..];
                v[..v.find('"').unwrap()].to_string()
            })
        };
        assert_eq!(get("format").as_deref(), Some("appended"));
        let offset: usize = get("offset").unwrap().parse().unwrap();
        let size = u64::from_le_bytes(data[offset..offset + 8].try_into().unwrap()) as usize;
        sum += 8 + size;
        let name = get("Name").unwrap_or_else(|| "Points".into());
        out.insert(
            name,
            (
                get("type").unwrap(),
                data[offset + 8..offset + 8 + size].to_vec(),
            ),
        );
    }
    assert_eq!(&data[sum..], b"\n</AppendedData>\n</VTKFile>\n");
    out
}

fn le_f64(b: &[u8]) -> Vec<f64> {
    b.chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

fn le_i32(b: &[u8]) -> Vec<f64> {
    b.chunks_exact(4)
        .map(|c| i32::from_le_bytes(c.try_into().unwrap()) as f64)
        .collect()
}

fn le_i64(b: &[u8]) -> Vec<f64> {
    b.chunks_exact(8)
        .map(|c| i64::from_le_bytes(c.try_into().unwrap()) as f64)
        .collect()
}

/// Binary PLY and VTU hold exactly what their ASCII forms hold (ASCII prints shortest
/// round-trip floats, so the numbers are equal bit for bit), for a curve, a surface and a
/// 3-manifold, and binary is the default.
#[test]
fn binary_ply_and_vtu_read_back_as_their_ascii_forms() {
    let out = dir("binary");
    for (name, params, m) in [
        ("circle", vec![], 1),
        ("torus", vec![("edge", 0.1)], 2),
        ("sphere", vec![("m", 3.0), ("d", 4.0), ("edge", 0.3)], 3),
    ] {
        let p = problem(name, &params);
        let c = build(&p);
        let mesh = Mesh::new(&c, Some(&p.system), &Projection::Auto, name);
        if m <= 2 {
            let (bin, asc) = (
                out.join(format!("{name}.b.ply")),
                out.join(format!("{name}.a.ply")),
            );
            write_mesh(&bin, &mesh, MeshFormat::Ply).unwrap();
            write_mesh_as(&asc, &mesh, MeshFormat::Ply, Encoding::Ascii).unwrap();
            let (head, verts, cells) = read_ply_binary(&std::fs::read(&bin).unwrap());
            let (nv, ascii_cells, ascii_head) = read_ply(&text(&asc));
            assert_eq!(
                head.replace("binary_little_endian", "ascii"),
                ascii_head + "end_header\n",
                "{name}"
            );
            assert_eq!(verts.len(), nv, "{name}");
            assert_eq!(cells, ascii_cells, "{name}");
            let ascii_verts: Vec<f64> = text(&asc)
                .split_once("end_header\n")
                .unwrap()
                .1
                .lines()
                .take(nv)
                .flat_map(floats)
                .collect();
            assert_eq!(verts.concat(), ascii_verts, "{name}");
            assert_eq!(verts.concat(), mesh.xyz, "{name}");
            assert!(
                std::fs::metadata(&bin).unwrap().len() < std::fs::metadata(&asc).unwrap().len()
            );
        }
        let (bin, asc) = (
            out.join(format!("{name}.b.vtu")),
            out.join(format!("{name}.a.vtu")),
        );
        write_mesh(&bin, &mesh, MeshFormat::Vtu).unwrap();
        write_mesh_as(&asc, &mesh, MeshFormat::Vtu, Encoding::Ascii).unwrap();
        let arrays = read_vtu_binary(&std::fs::read(&bin).unwrap());
        let s = text(&asc);
        let b = std::fs::read(&bin).unwrap();
        let xml_end = b.windows(13).position(|w| w == b"<AppendedData").unwrap();
        let head = std::str::from_utf8(&b[..xml_end]).unwrap();
        assert_eq!(
            attr(head, "NumberOfPoints"),
            attr(&s, "NumberOfPoints"),
            "{name}"
        );
        assert_eq!(
            attr(head, "NumberOfCells"),
            attr(&s, "NumberOfCells"),
            "{name}"
        );
        let f64s = |k: &str| {
            assert_eq!(arrays[k].0, "Float64", "{name} {k}");
            le_f64(&arrays[k].1)
        };
        let i64s = |k: &str| match arrays[k].0.as_str() {
            "Int64" => le_i64(&arrays[k].1),
            "Int32" => le_i32(&arrays[k].1),
            t => panic!("{name} {k}: {t}"),
        };
        let u8s = |k: &str| -> Vec<f64> {
            assert_eq!(arrays[k].0, "UInt8", "{name} {k}");
            arrays[k].1.iter().map(|&v| v as f64).collect()
        };
        assert_eq!(
            f64s("coordinates"),
            floats(vtu_array(&s, "coordinates")),
            "{name}"
        );
        assert_eq!(f64s("coordinates"), c.points(), "{name}");
        assert_eq!(f64s("Points"), mesh.xyz, "{name}");
        assert_eq!(
            i64s("connectivity"),
            floats(vtu_array(&s, "connectivity")),
            "{name}"
        );
        assert_eq!(i64s("offsets"), floats(vtu_array(&s, "offsets")), "{name}");
        assert_eq!(u8s("types"), floats(vtu_array(&s, "types")), "{name}");
        assert_eq!(u8s("boundary"), floats(vtu_array(&s, "boundary")), "{name}");
    }
    std::fs::remove_dir_all(out).unwrap();
}

#[test]
fn io_errors_keep_the_system_error_as_their_source() {
    use std::error::Error as _;
    let out = dir("io-source");
    let p = problem("circle", &[]);
    let c = build(&p);
    let mesh = Mesh::new(&c, Some(&p.system), &Projection::Auto, "circle");
    // The parent of the target is a regular file: the OS refuses, and says why.
    let file = out.join("plain");
    std::fs::write(&file, "x").unwrap();
    let e = write_mesh(&file.join("c.ply"), &mesh, MeshFormat::Ply).unwrap_err();
    assert!(matches!(e, isomesh::Error::Io { .. }), "{e:?}");
    let source = e.source().expect("a source");
    let io = source
        .downcast_ref::<std::io::Error>()
        .expect("an io::Error");
    assert!(e.to_string().ends_with(&io.to_string()), "{e}");
    assert!(e.to_string().contains("plain"), "{e}");
    // A refused target is not a system error: it has no source.
    let e = write_mesh(&out, &mesh, MeshFormat::Ply).unwrap_err();
    assert!(matches!(e, isomesh::Error::Output(_)), "{e:?}");
    assert!(e.source().is_none());
    let e = isomesh::expr::Spec::from_file(&out.join("absent.toml")).unwrap_err();
    let io = e
        .source()
        .unwrap()
        .downcast_ref::<std::io::Error>()
        .unwrap();
    assert_eq!(io.kind(), std::io::ErrorKind::NotFound);
    std::fs::remove_dir_all(out).unwrap();
}

/// The section's own topology: every segment in exactly two polygons (a closed surface), its
/// Euler characteristic, and its components (polygons joined through shared corners).
fn section_topology(s: &isomesh::export::section::Section) -> (i64, usize) {
    let mut uses: std::collections::HashMap<(u32, u32), u32> = Default::default();
    for p in &s.polygons {
        assert!(p.len() >= 3);
        for i in 0..p.len() {
            let (a, b) = (p[i], p[(i + 1) % p.len()]);
            *uses.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    assert!(
        uses.values().all(|&n| n == 2),
        "a segment not in two polygons"
    );
    let v = s.points.len() / s.dim;
    let chi = v as i64 - uses.len() as i64 + s.polygons.len() as i64;
    let mut parent: Vec<usize> = (0..v).collect();
    fn root(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    for &(a, b) in uses.keys() {
        let (ra, rb) = (root(&mut parent, a as usize), root(&mut parent, b as usize));
        parent[ra] = rb;
    }
    let components = (0..v).filter(|&i| root(&mut parent, i) == i).count();
    (chi, components)
}

#[test]
fn sections_of_closed_3_manifolds_are_closed_surfaces() {
    use isomesh::export::section::Section;
    // S^3 in R^4 by the hyperplane through its centre: one sphere.
    let c = build(&problem("sphere", &[("m", 3.0), ("d", 4.0), ("edge", 0.2)]));
    let s = Section::through_centroid(&c);
    assert_eq!(s.skipped, 0);
    assert_eq!(section_topology(&s), (2, 1));
    // Every corner on the hyperplane, and on S^3 up to the mesh's error.
    let n = [0.0, 0.0, 0.0, 1.0];
    let s = Section::of(&c, &n, 0.3).unwrap();
    assert_eq!(section_topology(&s), (2, 1));
    for x in s.points.chunks_exact(4) {
        assert!((x[3] - 0.3).abs() < 1e-12, "{x:?}");
        let r = x.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!((r - 1.0).abs() < 0.05, "{x:?}");
    }
    // Missing the sphere: nothing.
    assert!(Section::of(&c, &n, 1.5).unwrap().polygons.is_empty());
    // A normal of the wrong dimension is an error, not a panic.
    assert!(Section::of(&c, &[1.0, 0.0], 0.0).is_err());
    // The 3-torus by x6 = 0 (c sin t3 = 0, so t3 = 0 or pi): two 2-tori.
    let c = build(&problem("3-torus", &[("edge", 0.5)]));
    let s = Section::of(&c, &[0.0, 0.0, 0.0, 0.0, 0.0, 1.0], 0.0).unwrap();
    assert_eq!(s.skipped, 0);
    assert_eq!(section_topology(&s), (0, 2));
}
