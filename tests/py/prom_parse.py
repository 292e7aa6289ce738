"""Parses Prometheus text (standard input) with prometheus_client's own parser and prints
every sample as one JSON object per line: {"family", "type", "name", "labels", "value"}.
A text the parser refuses makes this script fail (a non-zero exit)."""
import json
import sys

from prometheus_client.parser import text_string_to_metric_families

text = sys.stdin.read()
for family in text_string_to_metric_families(text):
    for s in family.samples:
        print(json.dumps({
            "family": family.name,
            "type": family.type,
            "name": s.name,
            "labels": s.labels,
            "value": s.value,
        }))
