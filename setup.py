"""Builds the `microsim` extension with the project's CMake (target microsim_python) and installs it with
its type stub: `pip install --no-build-isolation .` (docs/guide/python.md). The CMake build folder is
$MICROSIM_BUILD_DIR, else build/ of the source tree (an existing build is reused, only the module is built)."""
import os
import pathlib
import shutil
import subprocess
import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = pathlib.Path(__file__).resolve().parent


def base_interpreter():
    """The interpreter a virtual environment was made from (the module's ABI is its)."""
    return getattr(sys, "_base_executable", sys.executable)


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        build = pathlib.Path(os.environ.get("MICROSIM_BUILD_DIR", ROOT / "build"))
        subprocess.check_call(["cmake", "-S", str(ROOT), "-B", str(build), "-DCMAKE_BUILD_TYPE=Release",
                               f"-DMICROSIM_PYTHON={base_interpreter()}", "-DMICROSIM_PYTHON_MODULE=ON"])
        subprocess.check_call(["cmake", "--build", str(build), "--target", "microsim_python",
                               f"-j{os.cpu_count() or 1}"])
        built = next((build / "python").glob("microsim*.so"))
        target = pathlib.Path(self.get_ext_fullpath(ext.name))
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(built, target)
        shutil.copy2(ROOT / "src" / "python" / "microsim.pyi", target.parent / "microsim.pyi")


# No Python packages (the module is the extension alone): no discovery of src/ as a package folder.
setup(ext_modules=[Extension("microsim", sources=[])], cmdclass={"build_ext": CMakeBuild}, packages=[], py_modules=[])
