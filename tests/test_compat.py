"""pyrender through fenestra.compat: NumPy 2 alias, EGL, and torch usable after GL in one process."""
import subprocess
import sys


def test_pyrender_then_torch_optimizer_in_one_process():
    # A child process, because the failure mode is a segfault of the whole interpreter.
    code = (
        "from fenestra.compat import import_pyrender\n"
        "pr = import_pyrender()\n"
        "r = pr.OffscreenRenderer(32, 24)\n"
        "import numpy as np, torch\n"
        "p = torch.nn.Parameter(torch.ones(3))\n"
        "opt = torch.optim.AdamW([p], lr=0.1)\n"
        "(p ** 2).sum().backward(); opt.step()\n"
        "s = pr.Scene(); s.add(pr.Mesh.from_points(np.zeros((1, 3)))); print(s.bounds.shape)\n"
        "r.delete(); print('ok', float(p[0]))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "(2, 3)" in out.stdout  # Scene.bounds works under NumPy 2 (np.infty alias)
    # First AdamW step by hand: p*(1 - lr*wd) - lr * m_hat/sqrt(v_hat) = 1*(1 - 0.1*0.01) - 0.1
    value = float(out.stdout.split("ok ")[1])
    assert abs(value - 0.899) < 1e-5
