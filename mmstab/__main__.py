from mmstab.cli import entry

entry()
