"""The wire: topic table, message conversions, CDR decoding."""
