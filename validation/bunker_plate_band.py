"""The long wall of the bunker under a static inside pressure, against thin plates of its
panel (docs/bunker.md §4): its centre deflection per unit pressure (m/Pa) at several mesh
sizes, beside the clamped and simply supported Kirchhoff plates (post/bunker.py), and where
it lies in that band.

    python validation/bunker_plate_band.py                          # bunker-h2's geometry
    python validation/bunker_plate_band.py --sizes 0.2 0.1 0.0667   # other meshes
    python validation/bunker_plate_band.py --set geometry.wall=0.1  # any variation

The static solve is the same mesh's, with its interface springs C = 10 E / h and its supports
(the base clamped), bulk and springs only (homogenise.static_long_wall_deflection); serial. Prints a
markdown table; exits 0 whatever it finds: it measures.
"""
import argparse

from dolfrag.reference import homogenise
from dolfrag.case import load_case
from dolfrag.post import bunker as bunker_post


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=float, nargs="+", default=[0.2, 0.1, 0.0667, 0.05])
    parser.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    args = parser.parse_args()
    case = load_case("bunker-h2", args.set)
    plates = bunker_post.plate_estimates(case.geometry, case.material)
    clamped, simple = plates["clamped_m_Pa"], plates["simply_supported_m_Pa"]
    print(f"panel {plates['span_m'][0]:g} m x {plates['span_m'][1]:g} m, {plates['thickness_m']:g} m thick: "
          f"clamped plate {clamped:.4g} m/Pa, simply supported {simple:.4g} m/Pa\n")
    print("| mesh.size (m) | tetrahedra | elements through the wall | w / p (m/Pa) | / clamped plate "
          "| / simply supported |")
    print("|---:|---:|---:|---:|---:|---:|")
    for size in args.sizes:
        cells, w = homogenise.static_long_wall_deflection(load_case("bunker-h2", args.set + [f"mesh.size={size}"]))
        print(f"| {size:g} | {cells:,} | {case.geometry.wall * case.geometry.scale / size:.1f} | {w:.4g} | "
              f"{w / clamped:.3f} | {w / simple:.3f} |", flush=True)


if __name__ == "__main__":
    main()
