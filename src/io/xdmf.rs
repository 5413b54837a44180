//! XDMF 3 description of a field file, so that ParaView (XDMF3 reader) or VisIt open it.

use std::fmt::Write as _;
use std::io;
use std::path::Path;

use super::atomic::atomic_write_bytes;
use crate::lattice::Grid;

/// The XDMF text describing the fields in HDF5 file `h5_name` (a path relative to the XDMF
/// file, usually just the file name) written by [`super::write_fields_h5`].
///
/// The mesh is a `3DCoRectMesh` with `Dimensions="nz ny nx"` (slowest first), origin 0 and
/// spacing 1: node `(x, y, z)` sits at lattice coordinates `(x, y, z)`. XDMF lists the
/// `ORIGIN_DXDYDZ` origin and spacing in the same z, y, x order.
pub fn xdmf_text(grid: Grid, time_step: u64, h5_name: &str) -> String {
    let dims = format!("{} {} {}", grid.nz, grid.ny, grid.nx);
    let mut s = String::new();
    let _ = write!(
        s,
        r#"<?xml version="1.0" ?>
<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>
<Xdmf Version="3.0" xmlns:xi="http://www.w3.org/2001/XInclude">
  <Domain>
    <Grid Name="fluid" GridType="Uniform">
      <Time Value="{time_step}"/>
      <Topology TopologyType="3DCoRectMesh" Dimensions="{dims}"/>
      <Geometry GeometryType="ORIGIN_DXDYDZ">
        <DataItem Name="Origin" Dimensions="3" NumberType="Float" Precision="8" Format="XML">0 0 0</DataItem>
        <DataItem Name="Spacing" Dimensions="3" NumberType="Float" Precision="8" Format="XML">1 1 1</DataItem>
      </Geometry>
      <Attribute Name="Density" AttributeType="Scalar" Center="Node">
        <DataItem Dimensions="{dims}" NumberType="Float" Precision="8" Format="HDF">{h5}:/density</DataItem>
      </Attribute>
      <Attribute Name="Velocity" AttributeType="Vector" Center="Node">
        <DataItem Dimensions="{dims} 3" NumberType="Float" Precision="8" Format="HDF">{h5}:/velocity</DataItem>
      </Attribute>
    </Grid>
  </Domain>
</Xdmf>
"#,
        h5 = xml_escape(h5_name),
    );
    s
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// Writes [`xdmf_text`] to `path` atomically.
pub fn write_xdmf(path: &Path, grid: Grid, time_step: u64, h5_name: &str) -> io::Result<()> {
    atomic_write_bytes(path, xdmf_text(grid, time_step, h5_name).as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_datasets_and_dimensions_slowest_first() {
        let t = xdmf_text(Grid::new(4, 5, 6), 7, "fields.h5");
        assert!(t.contains(r#"TopologyType="3DCoRectMesh" Dimensions="6 5 4""#));
        assert!(t.contains(">fields.h5:/density<"));
        assert!(t.contains(r#"Dimensions="6 5 4 3""#));
        assert!(t.contains(">fields.h5:/velocity<"));
        assert!(t.contains(r#"<Time Value="7"/>"#));
    }
}
