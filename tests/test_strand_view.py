"""The pyvistaqt strand view and the whole window on a real X server (Xvfb), in a subprocess."""
import os
import subprocess
import sys
import textwrap



SCRIPT = textwrap.dedent("""
    import sys, numpy as np
    from PySide6.QtWidgets import QApplication
    app = QApplication([])
    from hairdigi.app.gui.strand_view import StrandView
    from hairdigi.render.strands import hairstyle_strands
    view = StrandView()
    view.resize(400, 400)
    view.show()
    view.show_strands(hairstyle_strands("wavy", 300, seed=0), (160, 80, 40))
    app.processEvents()
    image = view.plotter.screenshot(return_img=True)
    view.plotter.camera.azimuth += 60    # rotate
    view.plotter.render()
    rotated = view.plotter.screenshot(return_img=True)
    import cv2
    cv2.imwrite(sys.argv[1], image[..., ::-1])
    hair = (np.abs(image.astype(int) - [160, 80, 40]).sum(axis=2) < 90).mean()
    print("std", image.std(), "hair", hair, "rotated_diff", np.abs(image.astype(int) - rotated).mean())
    view.close_view()
""")


def test_strand_view_under_xvfb(xvfb, test_output):
    out = test_output / "strand_view.png"
    env = {**os.environ, "DISPLAY": xvfb, "QT_QPA_PLATFORM": "xcb"}
    run = subprocess.run([sys.executable, "-c", SCRIPT, str(out)], env=env, capture_output=True, text=True,
                         timeout=180, cwd=os.path.dirname(os.path.dirname(__file__)))
    assert run.returncode == 0, run.stderr[-3000:]
    values = dict(zip(run.stdout.split()[::2], map(float, run.stdout.split()[1::2])))
    assert values["std"] > 5 and values["hair"] > 0.01     # strands drawn in the hair colour
    assert values["rotated_diff"] > 1                       # and the view rotates
    assert out.stat().st_size > 0
