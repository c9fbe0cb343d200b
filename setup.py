"""Build the compiled helpers: a CVODE driver on CasADi-generated C code with the sample loop
(``_cvode_compiled``, the simulator; it uses scikits.odes' Cython declarations of SUNDIALS) and a
CVODES driver with forward sensitivities (``_cvodes_sensitivity``, the fit), and paper 1's RLS
(``pneusim.online._rls``, the online identifier of the sample loop), and the fit's tracking filter
(``pneusim.fit._filter``).

scikits.odes ships its Cython declarations (.pxd) but not the small
``sundials_config.pxi`` they include; it is regenerated here from the installed
SUNDIALS headers so that our extension is compiled against the same types.
"""

import os
import re
from pathlib import Path

import numpy
from setuptools import Extension, setup

HERE = Path(__file__).parent
BUILD_INCLUDE = HERE / "build" / "pxi"


def sundials_config_pxi() -> Path:
    include = Path(os.environ.get("SUNDIALS_INCLUDEDIR", "/usr/include"))
    header = (include / "sundials" / "sundials_config.h").read_text()
    float_type = "double"
    for name, kind in (("SUNDIALS_SINGLE_PRECISION", "single"), ("SUNDIALS_EXTENDED_PRECISION", "extended")):
        if re.search(rf"^#define {name}\b", header, re.M):
            float_type = kind
    index = '"int32"' if re.search(r"^#define SUNDIALS_INT32_T\b", header, re.M) else '"64"'
    BUILD_INCLUDE.mkdir(parents=True, exist_ok=True)
    pxi = BUILD_INCLUDE / "sundials_config.pxi"
    pxi.write_text(f'DEF SUNDIALS_FLOAT_TYPE = "{float_type}"\nDEF SUNDIALS_INDEX_SIZE = {index}\n'
                   'DEF SUNDIALS_BLAS_LAPACK = False\n')
    return BUILD_INCLUDE


def extensions():
    from Cython.Build import cythonize
    import scikits.odes

    # the folder holding the scikits namespace, so that relative cimports resolve
    odes_root = Path(scikits.odes.__file__).resolve().parents[2]
    def solver_extension(name, cvode_library):
        return Extension(
            f"pneusim.solver.{name}", [f"pneusim/solver/{name}.pyx"],
            include_dirs=[numpy.get_include(), os.environ.get("SUNDIALS_INCLUDEDIR", "/usr/include"), "pneusim/solver"],
            libraries=[cvode_library, "sundials_nvecserial"],
            define_macros=[("NPY_NO_DEPRECATED_API", "NPY_1_7_API_VERSION")],
            # -ffp-contract=off: no fused multiply-adds, so that small_vector.h's a x + b y rounds as SUNDIALS' does
            extra_compile_args=["-g0", "-ffp-contract=off"],
            depends=["pneusim/solver/small_dense.h", "pneusim/solver/small_vector.h"],   # the Newton systems' solver: rebuild when it changes
        )

    # the online RLS of the sample loop (pneusim.online.PaperRLS): plain C, no SUNDIALS
    rls = Extension("pneusim.online._rls", ["pneusim/online/_rls.pyx"], include_dirs=[numpy.get_include()],
                    define_macros=[("NPY_NO_DEPRECATED_API", "NPY_1_7_API_VERSION")], extra_compile_args=["-g0"])
    # the tracking filter's pass (pneusim.fit.tracking.run_filter): plain C around the integrator's Python step
    tracking_filter = Extension("pneusim.fit._filter", ["pneusim/fit/_filter.pyx"], include_dirs=[numpy.get_include()],
                                define_macros=[("NPY_NO_DEPRECATED_API", "NPY_1_7_API_VERSION")],
                                extra_compile_args=["-g0", "-ffp-contract=off"])
    # the fit's CVODES driver with forward sensitivities declares what it uses itself
    return cythonize([solver_extension("_cvode_compiled", "sundials_cvode"),
                      solver_extension("_cvodes_sensitivity", "sundials_cvodes"), rls, tracking_filter], include_path=[str(sundials_config_pxi()), str(odes_root)],
                     compiler_directives={"language_level": 3}, quiet=True, nthreads=2)


# the three extensions cythonize and compile side by side, without debug information: the build is part
# of the README's one-command setup (docs/decisions/0052-setup-build-time.md)
setup(ext_modules=extensions(), options={"build_ext": {"parallel": 2}})
