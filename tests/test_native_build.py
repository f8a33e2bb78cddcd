"""ins.common.native_build.stale_kernels on a made-up source tree: a built module older
than its .pyx, or than a .pxd it cimports (directly or through another .pxd), is stale; a
missing one too; a current one is not."""
import os

from ins.common.native_build import stale_kernels


def _write(path, text, mtime):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    os.utime(path, (mtime, mtime))


def test_stale_kernels_follow_the_cimports(tmp_path):
    ins = tmp_path / "ins"
    _write(ins / "__init__.py", "", 100)
    _write(ins / "nav" / "_earth.pxd", "cdef inline double g(): return 9.8\n", 100)
    _write(ins / "nav" / "_step.pxd", "from ins.nav._earth cimport g\n", 100)
    _write(ins / "est" / "_k.pyx", "from ins.nav cimport _step as s\n", 100)
    _write(ins / "est" / "_other.pyx", "import numpy as np\n", 100)
    so_k = ins / "est" / "_k.cpython-311-x86_64-linux-gnu.so"
    _write(so_k, "", 200)
    assert stale_kernels(ins) == ["ins/est/_other.pyx"]        # never built
    _write(ins / "est" / "_other.cpython-311-x86_64-linux-gnu.so", "", 200)
    assert stale_kernels(ins) == []
    os.utime(ins / "nav" / "_earth.pxd", (300, 300))                 # two cimports away
    assert stale_kernels(ins) == ["ins/est/_k.pyx"]
    os.utime(so_k, (400, 400))
    assert stale_kernels(ins) == []
    os.utime(ins / "est" / "_k.pyx", (500, 500))
    assert stale_kernels(ins) == ["ins/est/_k.pyx"]


def test_this_installation_is_current():
    import photogrammetry
    assert stale_kernels() == []
    assert stale_kernels(os.path.dirname(photogrammetry.__file__)) == []
