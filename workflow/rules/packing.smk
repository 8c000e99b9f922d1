# Packing stage: virtual clay porous media by sequential deposition of elliptic disks
# (Ferrage et al. 2015), one job per entry of config["packings"].


rule packing_deposit:
    """Build, analyse and write one virtual clay packing (sequential deposition)."""
    output:
        result=run_path("packing/{packing}.nc"),
        figure=report(
            run_path("packing/{packing}.png"),
            caption="../report/packing.rst",
            category="5. Packing",
        ),
    params:
        code=script_code("packing_deposit.py"),
        section=get_packing_config,
    conda:
        "../envs/claychain.yaml"
    log:
        run_path("logs/packing_deposit/{packing}.log"),
    benchmark:
        run_path("benchmarks/packing_deposit/{packing}.tsv")
    script:
        "../scripts/packing_deposit.py"
