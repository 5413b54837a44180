"""Azimuthal means of the disk's flow on the (r, z) plane from a run's fields.h5 (s = 1/4): u_r, u_theta and
u_z over the tip speed, in 2-node rings about the axis, every 4th plane; then the radial jet against the swirl
just beyond the rim at mid-height, and the mean vertical flow above and below the disk between the rim and
r = 28. usage: python3 disk_flow.py RUN/run/fields.h5 [v_tip] (needs h5py, numpy)."""
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1], 'r')

v = f['velocity'][...]  # (nz, ny, nx, 3)
nz, ny, nx, _ = v.shape
vtip = float(sys.argv[2]) if len(sys.argv) > 2 else 0.1037
cx, cy = (nx - 1) / 2, (ny - 1) / 2
y, x = np.mgrid[0:ny, 0:nx]
dx, dy = x - cx, y - cy
r = np.hypot(dx, dy)
ex, ey = dx / np.maximum(r, 1e-9), dy / np.maximum(r, 1e-9)
ur = v[..., 0] * ex + v[..., 1] * ey
ut = -v[..., 0] * ey + v[..., 1] * ex
uz = v[..., 2]
R = 16.5  # disk radius at s = 1/4
zc = (nz - 1) / 2
print(f"grid {nx}x{ny}x{nz}, centre ({cx},{cy}), mid-plane z = {zc}")
rb = np.arange(0, 31, 2)
for name, comp in [('u_r', ur), ('u_theta', ut), ('u_z', uz)]:
    print(f"== {name}/v_tip: rows z, columns r = {[int(x) for x in rb[:-1]]}")
    for k in range(nz - 1, -1, -4):
        row = []
        for a, b in zip(rb[:-1], rb[1:]):
            m = (r >= a) & (r < b)
            row.append(comp[k][m].mean() / vtip)
        print(f"z={k:3d} z/H={(k+0.5)/nz:.2f} " + " ".join(f"{x:+.2f}" for x in row))
# jet strength: max |u_r| within 3 nodes of the mid-plane just beyond the rim, vs max u_theta there
band = slice(int(zc) - 3, int(zc) + 5)
m = (r > R) & (r < R + 6)
print("beyond the rim, near mid-plane: mean u_r/v_tip", ur[band][:, m].mean() / vtip, "mean u_theta/v_tip", ut[band][:, m].mean() / vtip)
# up-flow above the disk vs below: mean u_z at r in [R, 28] above/below
for zs, lab in [(slice(int(zc)+3, int(zc)+12), 'above'), (slice(int(zc)-12, int(zc)-3), 'below')]:
    mm = (r > R) & (r < 28)
    print(lab, "mean u_z/v_tip at R<r<28:", uz[zs][:, mm].mean() / vtip, " mean |u_r|:", np.abs(ur[zs][:, mm]).mean()/vtip)
