"""Check a ``.usdz`` with usd-core's ARKit compliance profile; print the findings as JSON.

Run by the tests (``tests/validators.py``: ``arkit_problems``) in the environment ``make validators`` makes,
``.venv-usdchecker``: usd-core 25.5, the last release that ships ``UsdUtils.ComplianceChecker`` (26.x
replaced it by ``UsdValidation``, whose validators hold no ARKit rules). It imports only ``pxr`` and the
standard library::

    .venv-usdchecker/bin/python tools/usd_arkit_check.py tree.usdz

prints ``{"errors": [...], "failed_checks": [...], "warnings": [...], "skipped": [...], "version": [0, 25,
5]}``: what ``usdchecker --arkit`` reports, the rules AR Quick Look's reader holds a file to.

One rule cannot run from a usd-core 25.x wheel: the wheels ship no shader definitions (no ``usdShaders``
plugin, and ``usdHydra`` without its ``shaderDefs.usda``), so ``ShaderPropertyTypeConformanceChecker``
fails on every shader ("Could not find shader resource", "invalid shader node"). It is then left out and named in
``skipped``; the same check (each shader input's type against its Sdr definition) is usd-core 26's
``usdShadeValidators:ShaderSdrCompliance``, which the tests run too (``usd_problems``).
"""

import json
import sys

from pxr import Sdr, Tf, Usd, UsdUtils
from pxr.UsdUtils import complianceChecker


def _shader_definitions_missing() -> bool:
    """Whether Sdr lacks UsdPreviewSurface (the discovery fails, raising here or on a thread of its own)."""
    try:
        return Sdr.Registry().GetShaderNodeByIdentifier("UsdPreviewSurface") is None
    except Tf.ErrorException:
        return True


def main(argv):
    if len(argv) != 2:
        raise SystemExit("usage: usd_arkit_check.py FILE.usdz")
    skipped = []
    if _shader_definitions_missing():
        rule = complianceChecker.ShaderPropertyTypeConformanceChecker
        rule.CheckPrim = lambda self, prim: None
        skipped.append(rule.__name__)
    checker = UsdUtils.ComplianceChecker(arkit=True, skipARKitRootLayerCheck=False, rootPackageOnly=False)
    checker.CheckCompliance(argv[1])
    report = {
        "errors": list(checker.GetErrors()),
        "failed_checks": list(checker.GetFailedChecks()),
        "warnings": list(checker.GetWarnings()),
        "skipped": skipped,
        "version": list(Usd.GetVersion()),
    }
    print(json.dumps(report))


if __name__ == "__main__":
    main(sys.argv)
