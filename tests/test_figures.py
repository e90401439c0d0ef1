import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pytest  # noqa: E402

from helpers import figures  # noqa: E402


def test_save_writes_png_and_pdf(tmp_path, monkeypatch):
    monkeypatch.setenv("WORKBOOK_FIGURES_DIR", str(tmp_path))
    figures.use_style()
    fig, ax = plt.subplots()
    ax.plot([0, 1], [1, 0])
    png, pdf = figures.save(fig, "unit_test_fig")
    plt.close(fig)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert pdf.read_bytes()[:5] == b"%PDF-"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["unit_test_fig.pdf", "unit_test_fig.png"]


def test_save_pdf_is_deterministic(tmp_path, monkeypatch):
    monkeypatch.setenv("WORKBOOK_FIGURES_DIR", str(tmp_path))
    fig, ax = plt.subplots()
    ax.plot([0, 1], [1, 0])
    _, pdf = figures.save(fig, "a")
    first = pdf.read_bytes()
    _, pdf = figures.save(fig, "a")
    plt.close(fig)
    assert pdf.read_bytes() == first


@pytest.mark.parametrize("name", ["", "../x", "a/b", "x.png", None])
def test_save_rejects_bad_names(name, tmp_path, monkeypatch):
    monkeypatch.setenv("WORKBOOK_FIGURES_DIR", str(tmp_path))
    fig, _ = plt.subplots()
    with pytest.raises(ValueError, match="name"):
        figures.save(fig, name)
    plt.close(fig)


def test_save_rejects_non_figure():
    with pytest.raises(ValueError, match="fig"):
        figures.save("not a figure", "x")
