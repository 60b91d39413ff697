"""Files written and read safely: atomic writes, the ownership mark and ledger, bounded readers, tables, images, poses."""
