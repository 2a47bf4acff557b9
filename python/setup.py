# `pip install ./python` (Debian's pip and setuptools, nothing downloaded): the pure-Python module over
# libegopd.so.0, which comes from `cmake --install` (set EGOPD_LIBRARY when it is not where the loader looks).
from setuptools import setup

setup(
    name="egopd",
    version="0.1.0",
    description="Grasp pressure from egocentric video with EgoPressureDiff on the CPU (ctypes over libegopd)",
    packages=["egopd"],
    python_requires=">=3.9",
    install_requires=["numpy"],
)
