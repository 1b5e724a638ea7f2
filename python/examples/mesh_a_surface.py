"""Mesh a surface from Python and look at it.

Run with `python examples/mesh_a_surface.py` after `pip install ./python`; it shows the mesh
with PyVista or matplotlib when one of them is installed, and writes torus.vtu either way.
"""

# %% A torus from its equation, traced from one seed.
import numpy as np

import isomesh

p = isomesh.Problem(["(sqrt(x^2 + y^2) - 1)^2 + z^2 - 0.16"], seeds=[[1.4, 0, 0]], edge=0.05)
s = p.trace()
print(f"{s.simplex_count} crossed edges in {s.report['elapsed_s']:.3f} s")

# %% The same torus as a vectorised NumPy function (CPU backend).
def torus(x):
    t = np.sqrt(x[:, 0] ** 2 + x[:, 1] ** 2) - 1.0
    return t * t + x[:, 2] ** 2 - 0.16

q = isomesh.Problem(function=torus, ambient_dim=3, codim=1, seeds=[[1.4, 0, 0]], edge=0.05)
print(f"the callable gives {q.trace().simplex_count} too")

# %% The cell complex, its topology, and files.
c = s.complex()
t = c.topology
print(f"cells {t['cells']}, Euler characteristic {t['euler_characteristic']}, "
      f"Betti numbers mod 2 {t['betti_mod2']}")
c.write("torus.vtu")

# %% Show it.
mesh = c.mesh_arrays()
try:
    import pyvista as pv

    faces = np.hstack([np.full((len(mesh["triangles"]), 1), 3), mesh["triangles"]]).ravel()
    pv.PolyData(mesh["points"], faces).plot(show_edges=True)
except ImportError:
    try:
        import matplotlib.pyplot as plt

        ax = plt.figure().add_subplot(projection="3d")
        xyz = mesh["points"]
        ax.plot_trisurf(xyz[:, 0], xyz[:, 1], xyz[:, 2], triangles=mesh["triangles"])
        ax.set_box_aspect((1, 1, 0.4))
        plt.show()
    except ImportError:
        print("install pyvista or matplotlib to see the mesh; torus.vtu opens in ParaView")
