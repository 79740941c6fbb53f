"""`usdface check`: USD's validators and usdface's schema rules on a file; exit 1 on errors."""
from __future__ import annotations

from ..options import NoOptions
from ..registry import Result
from ..usd.validation import check_layer


def check(file, *, options: NoOptions) -> Result:
    """Validate ``file`` (a path, layer or stage); ``exit_code`` 1 when a finding is an error."""
    findings = check_layer(file)
    errors = [f for f in findings if f.severity == "error"]
    summary = {"file": str(file) if not hasattr(file, "GetRootLayer") and not hasattr(file, "identifier")
               else getattr(file, "identifier", str(file)),
               "ok": not errors, "errors": len(errors), "findings": [f.__dict__ for f in findings]}
    return Result(summary=summary, text=[str(f) for f in findings] or ["no problems found"],
                  exit_code=1 if errors else 0, legacy=findings)
