"""The scripts of examples/python/ run end to end on a small aggregate (27 spheres)."""
import subprocess
import sys


def test_accretion_then_friction_sweep(source_dir, tmp_path):
    examples = source_dir / "examples" / "python"
    out = tmp_path / "acc"
    first = subprocess.run([sys.executable, examples / "accretion.py", "--n", "27", "--out", out],
                           capture_output=True, text=True)
    assert first.returncode == 0, first.stderr
    assert "at rest" in first.stdout and (out / "run.h5").exists() and (out / "metrics.png").exists()
    assert list((out / "checkpoints").glob("step-*.ckpt"))
    second = subprocess.run([sys.executable, examples / "friction_sweep.py", out, "--mu", "0", "0.5",
                             "--duration", "0.05"], capture_output=True, text=True)
    assert second.returncode == 0, second.stderr
    rows = [line for line in second.stdout.splitlines() if line.strip().startswith(("0.00", "0.50"))]
    assert len(rows) == 2, second.stdout
