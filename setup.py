"""`pip install .`: builds the module `bistable` with the project's CMake and installs it (docs/python.md).

    pip install --no-build-isolation --no-index .     # Debian's pip, setuptools, wheel; nothing downloaded

The compiled part, bistable._core, is the CMake target `_core` (python/CMakeLists.txt), built in the folder
BISTABLE_BUILD_DIR names (default: build/ of this tree, configured with Ninja and Release if it is not a
CMake build folder yet; an existing one is reused, so a tree already built installs in seconds). The pure
Python part is python/bistable/. The version is CMakeLists.txt's project version, as `bistable --version`,
the map files' software_version and bistable.__version__ say.
"""
import glob
import os
import re
import shutil
import sys
import sysconfig

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

HERE = os.path.dirname(os.path.abspath(__file__))


def project_version():
    with open(os.path.join(HERE, "CMakeLists.txt"), encoding="utf-8") as f:
        m = re.search(r"^project\(bistable_sweep VERSION (\d+\.\d+\.\d+)", f.read(), re.M)
    if not m:
        raise RuntimeError("CMakeLists.txt: no `project(bistable_sweep VERSION x.y.z` line")
    return m.group(1)


class CMakeBuild(build_ext):
    """Builds bistable._core with CMake (the extension has no sources of its own for setuptools)."""

    def build_extension(self, ext):
        build = os.path.abspath(os.environ.get("BISTABLE_BUILD_DIR") or os.path.join(HERE, "build"))
        if not os.path.exists(os.path.join(build, "CMakeCache.txt")):
            self.spawn(["cmake", "-S", HERE, "-B", build, "-G", "Ninja", "-DCMAKE_BUILD_TYPE=Release",
                        "-DPython3_EXECUTABLE=" + sys.executable])
        self.spawn(["cmake", "--build", build, "--target", "_core"])
        suffix = sysconfig.get_config_var("EXT_SUFFIX")
        built = os.path.join(build, "python", "bistable", "_core" + suffix)
        if not os.path.exists(built):
            found = glob.glob(os.path.join(build, "python", "bistable", "_core*.so"))
            raise RuntimeError("%s has %s, not _core%s for this Python (%s): build with the Python that runs pip, or "
                               "set BISTABLE_BUILD_DIR to a folder of its own" % (build, found or "no _core", suffix,
                                                                                sys.executable))
        dest = self.get_ext_fullpath(ext.name)
        os.makedirs(os.path.dirname(dest), exist_ok=True)
        shutil.copyfile(built, dest)


setup(
    version=project_version(),
    packages=["bistable"],
    package_dir={"": "python"},
    ext_modules=[Extension("bistable._core", sources=[])],
    cmdclass={"build_ext": CMakeBuild},
    # setuptools' own scratch (build/lib..., build/bdist...) apart from CMake's build folder
    options={"build": {"build_base": os.path.join("build", "setuptools")}},
    zip_safe=False,
)
