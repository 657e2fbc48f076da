"""Names of the HRIR database's asset kinds (declared in ``hairlut.assets.kinds``)."""

KIND = "hrir_db"
SHARD_KIND = "hrir_shard"
