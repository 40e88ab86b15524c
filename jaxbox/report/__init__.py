"""Self-contained HTML reports of a GreyBox: data, model selection, the accepted model."""

from ._html import greybox_report as greybox_report
from ._html import write_report as write_report
