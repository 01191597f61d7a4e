from mitlc.cli import run

run()
